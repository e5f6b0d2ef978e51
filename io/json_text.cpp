#include "io/json_text.h"

#include <array>
#include <cmath>

#include <nlohmann/json.hpp>

namespace shadowcull {

namespace {

// Printable ASCII without '"' or '\\': nlohmann's dump copies such a string unchanged.
bool plain(std::string_view s) {
    for (const char c : s) {
        const auto u = static_cast<unsigned char>(c);
        if (u < 0x20 || u > 0x7e || c == '"' || c == '\\') return false;
    }
    return true;
}

}  // namespace

JsonText::JsonText(std::string& out, size_t base) : out_(out), base_(base) {}

void JsonText::newLine(size_t depth) {
    out_ += '\n';
    out_.append(base_ + depth, ' ');
}

void JsonText::beforeValue() {
    if (afterKey_) {
        afterKey_ = false;
        return;
    }
    if (counts_.empty()) {
        // The top value: its first line indented by the base.
        if (!started_) out_.append(base_, ' ');
        started_ = true;
        return;
    }
    nextMember();  // an array element
}

void JsonText::nextMember() {
    if (counts_.back()++ > 0) out_ += ',';
    newLine(counts_.size());
}

void JsonText::key(std::string_view k) {
    nextMember();
    writeString(k);  // a key is printed as a string is
    out_ += ": ";
    afterKey_ = true;
}

void JsonText::open(char bracket) {
    beforeValue();
    out_ += bracket;
    counts_.push_back(0);
}

void JsonText::close(char bracket) {
    const size_t members = counts_.back();
    counts_.pop_back();
    if (members > 0) newLine(counts_.size());
    out_ += bracket;
}

void JsonText::value(std::string_view s) {
    beforeValue();
    writeString(s);
}

void JsonText::writeString(std::string_view s) {
    if (plain(s)) {
        out_ += '"';
        out_.append(s.data(), s.size());
        out_ += '"';
        return;
    }
    out_ += nlohmann::json(std::string(s)).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void JsonText::value(int64_t v) {
    beforeValue();
    out_ += std::to_string(v);
}

void JsonText::value(uint64_t v) {
    beforeValue();
    out_ += std::to_string(v);
}

void JsonText::value(double v) {
    beforeValue();
    if (!std::isfinite(v)) {
        out_ += "null";  // as nlohmann prints NaN and infinities
        return;
    }
    std::array<char, 64> buffer{};
    const char* end = nlohmann::detail::to_chars(buffer.data(), buffer.data() + buffer.size(), v);
    out_.append(buffer.data(), size_t(end - buffer.data()));
}

void JsonText::value(bool v) {
    beforeValue();
    out_ += v ? "true" : "false";
}

}  // namespace shadowcull
