#include "io/results_file.h"

#include <algorithm>
#include <limits>
#include <set>
#include <string_view>

#include <nlohmann/json.hpp>

#include "io/file_read.h"
#include "io/json_text.h"
#include "io/json_integer.h"

namespace shadowcull::results {

namespace {

using nlohmann::json;

// ---------------------------------------------------------------------------------------
// Writing

json vecJson(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

json lightJson(const LightRecord& L) {
    json j = {{"index", L.index}, {"bit", L.bit}, {"name", L.name}, {"type", L.type}};
    if (L.position) j["position"] = vecJson(*L.position);
    if (L.direction) j["direction"] = vecJson(*L.direction);
    for (const auto& [key, v] : {std::pair{"range", &L.range}, std::pair{"coneAngle", &L.coneAngle},
                                 std::pair{"bias", &L.bias}, std::pair{"slopeBias", &L.slopeBias},
                                 std::pair{"filterRadius", &L.filterRadius}, std::pair{"normalBias", &L.normalBias}})
        if (*v) j[key] = **v;
    return j;
}

json workJson(const WorkRecord& w) { return {{"casters", w.casters}, {"triangles", w.triangles}}; }

json savingsJson(const std::vector<LightSavingsRecord>& savings) {
    json a = json::array();
    for (const LightSavingsRecord& r : savings) {
        json by = json::object();
        for (const auto& [stage, w] : r.bakeCullsBy) by[stage] = workJson(w);
        a.push_back({{"light", r.light},
                     {"all", workJson(r.all)},
                     {"engineCulls", workJson(r.engineCulls)},
                     {"bakeCulls", workJson(r.bakeCulls)},
                     {"bakeCullsBy", std::move(by)},
                     {"undecided", workJson(r.undecided)}});
    }
    return a;
}

// The chunk's objects, the bulk of the file, are written as text directly (io/json_text.h:
// nlohmann's dump of the same value, byte for byte); each object's keys in std::map's
// order, as nlohmann's json object keeps them.
void vecText(JsonText& t, const glm::dvec3& v) {
    t.beginArray();
    t.value(v.x);
    t.value(v.y);
    t.value(v.z);
    t.endArray();
}

void boxText(JsonText& t, const BoxRecord& b) {
    t.beginArray();
    vecText(t, b[0]);
    vecText(t, b[1]);
    t.endArray();
}

// Members whose values are a point or a box: key(k), then the array.
void memberText(JsonText& t, std::string_view k, const glm::dvec3& v) {
    t.key(k);
    vecText(t, v);
}
void memberText(JsonText& t, std::string_view k, const BoxRecord& b) {
    t.key(k);
    boxText(t, b);
}

void witnessText(JsonText& t, const WitnessRecord& w) {
    t.beginObject();
    memberText(t, "direction", w.direction);
    memberText(t, "origin", w.origin);
    memberText(t, "p", w.p);
    memberText(t, "q", w.q);
    t.member("receiver", w.receiver);
    if (w.receiverBounds) memberText(t, "receiverBounds", *w.receiverBounds);
    t.endObject();
}

void bitText(JsonText& t, const BitRecord& b) {
    t.beginObject();
    t.member("bit", b.bit);
    t.member("light", b.light);
    if (!b.notes.empty()) {
        t.key("notes");
        t.beginArray();
        for (const auto& [stage, text] : b.notes) {
            t.beginObject();
            t.member("saw", text);
            t.member("stage", stage);
            t.endObject();
        }
        t.endArray();
    }
    // Left out when empty, as the bake always has: an undecided bit has neither.
    if (!b.reason.empty()) t.member("reason", b.reason);
    if (!b.stage.empty()) t.member("stage", b.stage);
    t.member("verdict", b.verdict);
    if (b.witness) {
        t.key("witness");
        witnessText(t, *b.witness);
    }
    t.endObject();
}

void groupText(JsonText& t, const GroupRecord& g) {
    t.beginObject();
    if (g.bounds) memberText(t, "bounds", *g.bounds);
    t.member("group", g.group);
    t.key("lights");
    t.beginArray();
    for (const BitRecord& b : g.lights) bitText(t, b);
    t.endArray();
    t.member("mask", g.mask);
    if (g.triangles) t.member("triangles", *g.triangles);
    t.endObject();
}

void objectText(JsonText& t, const ObjectRecord& o) {
    t.beginObject();
    t.member("element", o.element);
    if (!o.skipped) {
        t.key("groups");
        t.beginArray();
        for (const GroupRecord& g : o.groups) groupText(t, g);
        t.endArray();
    }
    t.member("kind", o.kind);
    // A skipped object: the bake could not use it; no verdicts to give, no mask written.
    if (o.skipped) t.member("skipped", true);
    else t.member("mask", o.mask);
    if (!o.uuid.empty()) t.member("uuid", o.uuid);
    t.endObject();
}

// `text` (nlohmann's dump with indent 1, which never puts a raw newline inside a string)
// moved right by `spaces`, as it would be printed nested that deep.
std::string indented(const std::string& text, size_t spaces) {
    const std::string pad(spaces, ' ');
    std::string out = pad;
    out.reserve(text.size() + text.size() / 8);
    for (char c : text) {
        out += c;
        if (c == '\n') out += pad;
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// Reading

// Thrown inside the parser only (never out of this file): one message, turned into an
// Error with the file name and the JSON path where it happened.
struct BadContent {
    std::string message;
};

// nlohmann messages start with "[json.exception.type_error.302] "; the rest is the point.
std::string jsonMessage(const std::exception& e) {
    std::string w = e.what();
    const size_t k = w.find("] ");
    return k == std::string::npos ? w : w.substr(k + 2);
}

// An integer field: a JSON integer (neither 2.5 nor 1e308: converting those is undefined)
// within T's range.
template <class T>
T integer(const json& o, const char* key) {
    const json& v = o.at(key);
    const std::string what = std::string("'") + key + "' ";
    if (!v.is_number_integer()) throw BadContent{what + "must be an integer, not " + v.dump()};
    const std::optional<T> n = integerIn<T>(v);
    if (!n) throw BadContent{what + v.dump() + " is out of range"};
    return *n;
}

glm::dvec3 readVec(const json& a) {
    if (!a.is_array() || a.size() != 3) throw BadContent{"expected [x, y, z]"};
    return {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
}

BoxRecord readBox(const json& a) {
    if (!a.is_array() || a.size() != 2) throw BadContent{"expected [[x, y, z], [x, y, z]]"};
    return {readVec(a[0]), readVec(a[1])};
}

// The fields are read in the order `shadowcull diff` always read them, so that a file with
// several faults is reported by the first, as before.
BitRecord readBit(const json& jl, int light) {
    BitRecord b;
    b.light = light;
    b.bit = integer<int>(jl, "bit");
    b.verdict = jl.at("verdict").get<std::string>();
    b.stage = jl.value("stage", std::string());
    b.reason = jl.value("reason", std::string());
    if (jl.contains("notes") && jl["notes"].is_array())
        for (const json& n : jl["notes"]) b.notes.emplace_back(n.value("stage", std::string()), n.value("saw", std::string()));
    if (jl.contains("witness")) {
        const json& w = jl["witness"];
        b.witness = WitnessRecord{readVec(w.at("origin")), readVec(w.at("direction")), readVec(w.at("p")),
                                  readVec(w.at("q")), w.value("receiver", std::string()), std::nullopt};
        if (w.contains("receiverBounds")) b.witness->receiverBounds = readBox(w["receiverBounds"]);
    }
    return b;
}

// One object. `where` is kept pointing at the part being read, so that an error names it
// ("chunks[0].objects[2].groups[1]").
ObjectRecord readObject(const json& jo, const std::string& at, std::string& where) {
    where = at;
    ObjectRecord o;
    o.element = integer<int>(jo, "element");
    o.kind = jo.at("kind").get<std::string>();
    o.uuid = jo.value("uuid", std::string());
    o.skipped = jo.value("skipped", false);
    if (o.skipped) return o;
    o.mask = integer<uint32_t>(jo, "mask");
    for (const json& jg : jo.at("groups")) {
        const std::string ga = at + ".groups[" + std::to_string(o.groups.size()) + "]";
        where = ga;
        if (integer<size_t>(jg, "group") != o.groups.size()) throw BadContent{"groups out of order"};
        GroupRecord g;
        g.group = int(o.groups.size());
        g.mask = integer<uint32_t>(jg, "mask");
        if (jg.contains("bounds")) g.bounds = readBox(jg["bounds"]);
        if (jg.contains("triangles")) g.triangles = integer<uint64_t>(jg, "triangles");
        for (const json& jl : jg.at("lights")) {
            where = ga + ".lights[" + std::to_string(g.lights.size()) + "]";
            if (integer<size_t>(jl, "light") != g.lights.size() + 1) throw BadContent{"lights out of order"};
            g.lights.push_back(readBit(jl, int(g.lights.size()) + 1));
        }
        o.groups.push_back(std::move(g));
    }
    return o;
}

WorkRecord readWork(const json& j) { return {integer<uint64_t>(j, "casters"), integer<uint64_t>(j, "triangles")}; }

std::vector<LightSavingsRecord> readSavings(const json& a) {
    if (!a.is_array()) throw BadContent{"'savings' must be an array, not " + a.dump()};
    std::vector<LightSavingsRecord> v;
    for (const json& j : a) {
        LightSavingsRecord r;
        r.light = integer<int>(j, "light");
        r.all = readWork(j.at("all"));
        r.engineCulls = readWork(j.at("engineCulls"));
        r.bakeCulls = readWork(j.at("bakeCulls"));
        r.undecided = readWork(j.at("undecided"));
        if (j.contains("bakeCullsBy"))
            for (auto it = j["bakeCullsBy"].begin(); it != j["bakeCullsBy"].end(); ++it) r.bakeCullsBy[it.key()] = readWork(it.value());
        v.push_back(std::move(r));
    }
    return v;
}

Summary readSummary(const json& js) {
    Summary s;
    s.chunks = integer<uint64_t>(js, "chunks");
    s.groups = integer<uint64_t>(js, "groups");
    s.bits = integer<uint64_t>(js, "bits");
    s.kept = integer<uint64_t>(js, "kept");
    s.culled = integer<uint64_t>(js, "culled");
    s.provedKept = integer<uint64_t>(js, "provedKept");
    s.undecided = integer<uint64_t>(js, "undecided");
    const json& by = js.at("culledBy");
    if (!by.is_object()) throw BadContent{"'culledBy' must be an object, not " + by.dump()};
    for (auto it = by.begin(); it != by.end(); ++it) s.culledBy[it.key()] = integer<uint64_t>(by, it.key().c_str());
    if (js.contains("savings")) s.savings = readSavings(js["savings"]);
    return s;
}

Error badInput(const std::string& path, int line, std::string message) {
    return makeError(ErrorKind::BadInput, path, line, std::move(message));
}

// Bad content at `where`, a JSON path ("chunks[0].objects[2].groups[1]").
Error malformedAt(const std::string& path, const std::string& where, const std::string& message) {
    return badInput(path, 0, "malformed results at " + where + ": " + message);
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Writing

// Pretty-printed with an indent of one space. Text that is not valid UTF-8 (a space path
// or a file name in Latin-1) is written with U+FFFD in place of the bad bytes: the file
// stays valid JSON, and the bake does not die at its very end (nlohmann throws otherwise).
std::string dumped(const json& j) { return j.dump(1, ' ', false, json::error_handler_t::replace); }

// A chunk sits two levels deep (in the top-level object's "chunks" array), its objects four
// (in its "objects" array); its keys sort as "chunk", "objects", "savings", "simulated", so
// the pieces below are nlohmann's dump of the whole chunk cut around its objects.
std::string chunkOpenJson(const std::string& chunk) {
    return "  {\n   \"chunk\": " + dumped(json(chunk)) + ",\n   \"objects\": [";
}

std::string chunkObjectJson(const ObjectRecord& object) {
    std::string text;
    JsonText t(text, 4);
    objectText(t, object);
    return text;
}

std::string chunkCloseJson(const ChunkRecord& chunk, bool anyObject) {
    json j;
    j["simulated"] = chunk.simulated;
    if (!chunk.savings.empty()) j["savings"] = savingsJson(chunk.savings);
    // The keys after "objects" are this object's dump, as deep as the chunk, without its "  {\n".
    const std::string rest = indented(dumped(j), 2);
    return std::string(anyObject ? "\n   ]" : "]") + ",\n" + rest.substr(4);
}

std::string chunkJson(const ChunkRecord& chunk) {
    std::string text = chunkOpenJson(chunk.chunk);
    for (size_t k = 0; k < chunk.objects.size(); ++k) {
        text += k == 0 ? "\n" : ",\n";
        JsonText t(text, 4);  // chunkObjectJson's text, written in place
        objectText(t, chunk.objects[k]);
    }
    return text += chunkCloseJson(chunk, !chunk.objects.empty());
}

std::string resultsHead() { return "{\n \"chunks\": ["; }

std::string resultsTail(const ResultsFile& file, bool anyChunk) {
    json j;
    j["format"] = kFormat;
    j["version"] = file.version;
    j["space"] = file.space;
    json lights = json::array();
    for (const LightRecord& L : file.lights)
        lights.push_back(lightJson(L));
    j["lights"] = std::move(lights);
    const Summary& s = file.summary;
    json culledBy = json::object();
    for (const auto& [stage, n] : s.culledBy) culledBy[stage] = n;
    j["summary"] = {{"chunks", s.chunks},      {"groups", s.groups},         {"bits", s.bits},
                    {"kept", s.kept},          {"culled", s.culled},         {"provedKept", s.provedKept},
                    {"undecided", s.undecided}, {"culledBy", std::move(culledBy)}};
    if (!s.savings.empty()) j["summary"]["savings"] = savingsJson(s.savings);
    j["warnings"] = file.warnings;
    if (file.shard) {
        const ShardRecord& sh = *file.shard;
        j["shard"] = {{"index", sh.index},           {"count", sh.count},
                      {"inputs", sh.inputs},         {"spaceChunks", sh.spaceChunks},
                      {"assigned", sh.assigned},     {"spaceWarnings", sh.spaceWarnings}};
    }
    // Every other key sorts after "chunks" (nlohmann's json keeps keys sorted), so the rest
    // of the file is this object's dump without its opening brace.
    const std::string rest = dumped(j);
    return std::string(anyChunk ? "\n ]" : "]") + ",\n" + rest.substr(2) + "\n";
}

std::string writeResults(const ResultsFile& file) {
    std::string text = resultsHead();
    for (size_t k = 0; k < file.chunks.size(); ++k) {
        text += k == 0 ? "\n" : ",\n";
        text += chunkJson(file.chunks[k]);
    }
    return text + resultsTail(file, !file.chunks.empty());
}

void Summary::count(const ChunkRecord& c) {
    ++chunks;
    for (const ObjectRecord& o : c.objects) countObject(o);
}

void Summary::countObject(const ObjectRecord& o) {
    if (o.skipped) return;
    groups += o.groups.size();
    for (const GroupRecord& g : o.groups)
        for (const BitRecord& b : g.lights) {
            ++bits;
            if (b.verdict == "culled") {
                ++culled;
                ++culledBy[b.stage];
            } else {
                ++kept;  // written 1: with a witness, or because nobody could decide
                ++(b.verdict == "kept" ? provedKept : undecided);
            }
        }
}

Summary summarize(const std::vector<ChunkRecord>& chunks) {
    Summary s;
    for (const ChunkRecord& c : chunks) s.count(c);
    return s;
}

// ---------------------------------------------------------------------------------------
// Reading

Expected<ChunkRecord> parseChunkJson(const std::string& path, const std::string& text) {
    Expected<ResultsFile> f = parseResults(path, resultsHead() + "\n" + text + resultsTail(ResultsFile{}, true));
    if (!f) return f.error();
    if (f->chunks.size() != 1) return badInput(path, 0, "malformed results: not one chunk");
    return std::move(f->chunks.front());
}

Expected<ResultsFile> readResultsFile(const std::string& path) {
    Expected<std::string> text = readRegularFile(path, "results file");
    if (!text) return text.error();
    return parseResults(path, *text);
}

Expected<ResultsFile> parseResults(const std::string& path, const std::string& text) {
    json j;
    try {
        j = json::parse(text);
    } catch (const json::parse_error& e) {
        // e.byte is 1-based and points at the character that broke the parse.
        const size_t at = std::min(text.size(), e.byte > 0 ? size_t(e.byte - 1) : size_t(0));
        const size_t line = 1 + size_t(std::count(text.begin(), text.begin() + std::ptrdiff_t(at), '\n'));
        std::string msg = jsonMessage(e);
        if (size_t k = msg.find("column"); k != std::string::npos && msg.find(": ", k) != std::string::npos)
            msg = msg.substr(msg.find(": ", k) + 2);
        return badInput(path, int(std::min<size_t>(line, size_t(std::numeric_limits<int>::max()))),
                        "malformed JSON: " + msg);
    } catch (const json::exception& e) {
        // A number too large for a double (1e400) is out_of_range, not a parse error.
        return badInput(path, 0, "malformed JSON: " + jsonMessage(e));
    }
    if (!j.is_object() || !j.contains("format") || j["format"] != kFormat)
        return badInput(path, 0,
                        std::string("not a shadowcull results file (expected \"format\": \"") + kFormat + "\")");
    ResultsFile f;
    std::string where = "top level";
    try {
        f.version = integer<int>(j, "version");
        if (f.version != kVersion)
            throw BadContent{"unsupported version " + j["version"].dump() + " (this tool reads version " +
                             std::to_string(kVersion) + ")"};
        for (const json& L : j.at("lights")) {
            where = "lights[" + std::to_string(f.lights.size()) + "]";
            LightRecord r;
            r.name = L.at("name").get<std::string>();
            r.type = L.at("type").get<std::string>();
            r.bit = L.contains("bit") ? integer<int>(L, "bit") : int(f.lights.size());
            r.index = L.contains("index") ? integer<int>(L, "index") : int(f.lights.size()) + 1;
            if (L.contains("position")) r.position = readVec(L["position"]);
            if (L.contains("direction")) r.direction = readVec(L["direction"]);
            for (const auto& [key, v] : {std::pair{"range", &r.range}, std::pair{"coneAngle", &r.coneAngle},
                                         std::pair{"bias", &r.bias}, std::pair{"slopeBias", &r.slopeBias},
                                         std::pair{"filterRadius", &r.filterRadius},
                                         std::pair{"normalBias", &r.normalBias}})
                if (L.contains(key)) *v = L[key].get<double>();
            f.lights.push_back(std::move(r));
        }
        size_t ci = 0;
        std::set<std::string> names;  // chunk names seen
        for (const json& jc : j.at("chunks")) {
            const std::string ca = "chunks[" + std::to_string(ci++) + "]";
            where = ca;
            ChunkRecord c;
            c.chunk = jc.at("chunk").get<std::string>();
            if (!names.insert(c.chunk).second) throw BadContent{"chunk " + c.chunk + " appears twice"};
            if (jc.contains("simulated")) c.simulated = jc["simulated"].get<std::vector<std::string>>();
            for (const json& jo : jc.at("objects"))
                c.objects.push_back(readObject(jo, ca + ".objects[" + std::to_string(c.objects.size()) + "]", where));
            where = ca;
            if (jc.contains("savings")) c.savings = readSavings(jc["savings"]);
            f.chunks.push_back(std::move(c));
        }
        // What follows was never needed by diff: read after the chunks, so that a fault in
        // them is still the one reported.
        where = "top level";
        if (j.contains("space")) f.space = j["space"].get<std::string>();
        if (j.contains("warnings")) f.warnings = j["warnings"].get<std::vector<std::string>>();
        if (j.contains("shard")) {
            where = "shard";
            const json& js = j["shard"];
            ShardRecord sh;
            sh.index = integer<int>(js, "index");
            sh.count = integer<int>(js, "count");
            if (sh.count < 1 || sh.index < 1 || sh.index > sh.count)
                throw BadContent{"shard " + std::to_string(sh.index) + " of " + std::to_string(sh.count) + " does not exist"};
            sh.inputs = js.at("inputs").get<std::string>();
            sh.spaceChunks = integer<uint64_t>(js, "spaceChunks");
            sh.assigned = js.at("assigned").get<std::vector<std::string>>();
            sh.spaceWarnings = integer<uint64_t>(js, "spaceWarnings");
            if (sh.spaceWarnings > f.warnings.size()) throw BadContent{"spaceWarnings is more than the warnings"};
            f.shard = std::move(sh);
        }
        if (j.contains("summary")) {
            where = "summary";
            f.summary = readSummary(j["summary"]);
        } else {
            f.summary = summarize(f.chunks);
        }
    } catch (const json::exception& e) {
        return malformedAt(path, where, jsonMessage(e));
    } catch (const BadContent& e) {
        return malformedAt(path, where, e.message);
    }
    return f;
}

Expected<ObjectRecord> parseObjectJson(const std::string& path, const std::string& text) {
    const std::string at = "object";
    std::string where = at;
    try {
        return readObject(json::parse(text), at, where);
    } catch (const json::exception& e) {
        return malformedAt(path, where, jsonMessage(e));
    } catch (const BadContent& e) {
        return malformedAt(path, where, e.message);
    }
}

}  // namespace shadowcull::results
