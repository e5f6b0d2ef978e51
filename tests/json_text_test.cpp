// io/json_text.h: JSON text written directly must be nlohmann's dump of the same value, byte
// for byte (the results file's layout, which merge, export, diff and the determinism tests
// compare as bytes). Random values against nlohmann itself: nesting, empty containers,
// keys and strings with quotes, control bytes, UTF-8 and invalid UTF-8, integers of both
// signs and doubles from denormals to infinities; then random results objects, written by
// results::chunkObjectJson, against nlohmann's dump of the parsed text.

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io/json_text.h"
#include "io/results_file.h"

using namespace shadowcull;
using nlohmann::json;

namespace {

std::string randomString(std::mt19937_64& rng) {
    static const std::vector<std::string> pieces = {"a", "Z", "0", " ", "\"", "\\", "/", "\n", "\t", "\x01", "\x1f",
                                                    "\x7f", "\xc3\xa9", "\xe2\x82\xac", "\xf0\x9f\x98\x80",
                                                    "\xff", "\xc3", "\xe2\x82", "\xed\xa0\x80", "group 0", "#"};
    std::string s;
    const int n = int(rng() % 6);
    for (int k = 0; k < n; ++k) s += pieces[rng() % pieces.size()];
    return s;
}

double randomDouble(std::mt19937_64& rng) {
    switch (rng() % 8) {
        case 0: return 0.0;
        case 1: return -0.0;
        case 2: return std::numeric_limits<double>::denorm_min() * double(rng() % 1000 + 1);
        case 3: return std::numeric_limits<double>::infinity();
        case 4: return std::nan("");
        case 5: return double(int64_t(rng() % 2001) - 1000);
        default: {
            double d;
            uint64_t bits = rng();
            std::memcpy(&d, &bits, sizeof d);
            return std::isfinite(d) ? d : 1.5e300;
        }
    }
}

json randomValue(std::mt19937_64& rng, int depth) {
    switch (rng() % (depth > 3 ? 5 : 7)) {
        case 0: return randomString(rng);
        case 1: return int64_t(rng()) >> (rng() % 64);
        case 2: return uint64_t(rng()) >> (rng() % 64);
        case 3: return randomDouble(rng);
        case 4: return rng() % 2 == 0;
        case 5: {
            json a = json::array();
            const int n = int(rng() % 4);
            for (int k = 0; k < n; ++k) a.push_back(randomValue(rng, depth + 1));
            return a;
        }
        default: {
            json o = json::object();
            const int n = int(rng() % 4);
            for (int k = 0; k < n; ++k) o[randomString(rng)] = randomValue(rng, depth + 1);
            return o;
        }
    }
}

// The value written through JsonText, members in the json's own (sorted) order.
void write(JsonText& t, const json& j) {
    switch (j.type()) {
        case json::value_t::object:
            t.beginObject();
            for (const auto& [k, v] : j.items()) {
                t.key(k);
                write(t, v);
            }
            t.endObject();
            break;
        case json::value_t::array:
            t.beginArray();
            for (const json& v : j) write(t, v);
            t.endArray();
            break;
        case json::value_t::string: t.value(j.get_ref<const std::string&>()); break;
        case json::value_t::number_integer: t.value(j.get<int64_t>()); break;
        case json::value_t::number_unsigned: t.value(j.get<uint64_t>()); break;
        case json::value_t::number_float: t.value(j.get<double>()); break;
        case json::value_t::boolean: t.value(j.get<bool>()); break;
        default: FAIL() << "unexpected type";
    }
}

std::string dumped(const json& j) { return j.dump(1, ' ', false, json::error_handler_t::replace); }

// nlohmann's dump moved right by `spaces`, as io/results_file.cpp nests an object.
std::string indented(const std::string& text, size_t spaces) {
    std::string out(spaces, ' ');
    for (char c : text) {
        out += c;
        if (c == '\n') out.append(spaces, ' ');
    }
    return out;
}

}  // namespace

TEST(JsonText, IsNlohmannsDumpOfRandomValues) {
    std::mt19937_64 rng(20261207);
    for (int trial = 0; trial < 3000; ++trial) {
        const json j = randomValue(rng, 0);
        for (size_t base : {size_t(0), size_t(4)}) {
            std::string text;
            JsonText t(text, base);
            write(t, j);
            ASSERT_EQ(text, indented(dumped(j), base)) << "trial " << trial << ", base " << base;
        }
    }
}

TEST(JsonText, ResultsObjectsAreNlohmannsDump) {
    std::mt19937_64 rng(7);
    for (int trial = 0; trial < 500; ++trial) {
        results::ObjectRecord o;
        o.element = int(rng() % 100) - 1;
        o.kind = rng() % 2 ? "model" : "terrain";
        if (rng() % 2) o.uuid = randomString(rng);
        o.skipped = rng() % 5 == 0;
        o.mask = uint32_t(rng());
        for (int g = 0, n = int(rng() % 3); g < n && !o.skipped; ++g) {
            results::GroupRecord gr;
            gr.group = g;
            gr.mask = uint32_t(rng() % 4);
            if (rng() % 2) gr.bounds = results::BoxRecord{glm::dvec3(randomDouble(rng), 1.0, -2.5), glm::dvec3(3.0)};
            if (rng() % 2) gr.triangles = rng();
            for (int l = 1, m = int(rng() % 3); l <= m; ++l) {
                results::BitRecord b;
                b.light = l;
                b.bit = int(rng() % 2);
                b.verdict = randomString(rng);
                if (rng() % 2) b.stage = randomString(rng);
                if (rng() % 2) b.reason = randomString(rng);
                for (int k = 0, nn = int(rng() % 3); k < nn; ++k) b.notes.emplace_back(randomString(rng), randomString(rng));
                if (rng() % 2) {
                    results::WitnessRecord w;
                    w.origin = {randomDouble(rng), randomDouble(rng), 0.1};
                    w.direction = {0.0, -1.0, randomDouble(rng)};
                    w.p = {1e-300, 5.0, 6.0};
                    w.q = {randomDouble(rng), 8.0, 9.0};
                    w.receiver = randomString(rng);
                    if (rng() % 2) w.receiverBounds = results::BoxRecord{glm::dvec3(-1.0), glm::dvec3(randomDouble(rng))};
                    b.witness = w;
                }
                gr.lights.push_back(b);
            }
            o.groups.push_back(gr);
        }
        const std::string text = results::chunkObjectJson(o);
        // Parsed back (invalid UTF-8 was written as U+FFFD, NaN and infinities as null):
        // nlohmann's dump of that value, four spaces deep, is the same text.
        const json j = json::parse(text);
        ASSERT_EQ(text, indented(dumped(j), 4)) << "trial " << trial;
    }
}
