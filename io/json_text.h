// JSON text written straight into a string, byte for byte as nlohmann::json's
// dump(1, ' ', false, error_handler_t::replace) prints the same value (the results file's
// format: io/results_file.cpp), without building the json tree first: the results file of
// a 400-chunk world holds about a million values, and the tree (a std::map per object, a
// node per value) cost the bake's main thread more than a second on world R.
//
// The caller gives each object's keys in nlohmann's order (std::map's: sorted bytewise)
// and each number in the C++ type nlohmann would store it as (a signed or unsigned
// integer, or a double). Strings of plain printable ASCII are copied; any other string is
// escaped by nlohmann itself, and doubles are formatted by its to_chars (Grisu2), so the
// text is nlohmann's wherever the two could differ.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace shadowcull {

class JsonText {
public:
    // Appends to `out`, the value nested `base` spaces deep: its first line starts with
    // `base` spaces, every later line with `base` more than nlohmann's dump gives it.
    JsonText(std::string& out, size_t base);

    void beginObject() { open('{'); }
    void endObject() { close('}'); }
    void beginArray() { open('['); }
    void endArray() { close(']'); }
    // The next member's key (inside an object; the value follows).
    void key(std::string_view k);
    // A member whose value is one of value()'s: key(k), then value(v).
    template <class T>
    void member(std::string_view k, const T& v) {
        key(k);
        value(v);
    }

    void value(std::string_view s);
    void value(const char* s) { value(std::string_view(s)); }
    void value(int64_t v);
    void value(int v) { value(int64_t(v)); }
    void value(uint64_t v);
    void value(uint32_t v) { value(uint64_t(v)); }
    void value(double v);
    void value(bool v);

private:
    void open(char bracket);   // an object or an array, as a value
    void close(char bracket);  // its end: on a line of its own unless it is empty
    void beforeValue();  // the separator and indentation an array element or a top value needs
    void nextMember();   // the separator and new line before the open container's next member
    void newLine(size_t depth);
    void writeString(std::string_view s);  // quoted and escaped as nlohmann's dump does

    std::string& out_;
    size_t base_;
    std::vector<size_t> counts_;  // per open container: its members so far
    bool afterKey_ = false;
    bool started_ = false;
};

}  // namespace shadowcull
