#include "io/results_stream.h"

#include <sys/stat.h>

#include <fstream>
#include <iterator>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

namespace shadowcull::results {

namespace {

using nlohmann::json;

// The lines writeResults puts around and between the chunks and their objects: indent 1 for
// the file's keys, 2 for a chunk's braces, 3 for its keys, 4 for an object's braces. JSON
// strings hold no raw newline, so a line of the layout is never inside a string.
constexpr const char* kChunksOpen = " \"chunks\": [";
constexpr const char* kChunksClose = " ],";
constexpr const char* kChunkOpen = "  {";
constexpr const char* kChunkClose = "  }";
constexpr const char* kChunkCloseMore = "  },";
constexpr const char* kChunkName = "   \"chunk\": ";  // the name, then ","
constexpr const char* kObjectsOpen = "   \"objects\": [";
constexpr const char* kObjectsNone = "   \"objects\": []";  // then "," unless last
constexpr const char* kObjectsClose = "   ]";
constexpr const char* kObjectsCloseMore = "   ],";
constexpr const char* kObjectOpen = "    {";
constexpr const char* kObjectClose = "    }";
constexpr const char* kObjectCloseMore = "    },";

// A SAX handler (nlohmann's interface) that keeps only the keys of each object open.
struct KeyRepeatFinder {
    std::vector<std::set<std::string>> open;
    bool repeated = false;

    bool null() { return true; }
    bool boolean(bool) { return true; }
    bool number_integer(json::number_integer_t) { return true; }
    bool number_unsigned(json::number_unsigned_t) { return true; }
    bool number_float(json::number_float_t, const json::string_t&) { return true; }
    bool string(json::string_t&) { return true; }
    bool binary(json::binary_t&) { return true; }
    bool start_object(std::size_t) {
        open.emplace_back();
        return true;
    }
    bool key(json::string_t& k) {
        repeated = !open.back().insert(k).second;
        return !repeated;
    }
    bool end_object() {
        open.pop_back();
        return true;
    }
    bool start_array(std::size_t) { return true; }
    bool end_array() { return true; }
    bool parse_error(std::size_t, const std::string&, const json::exception&) { return false; }
};

// Whether `text` is one JSON value by itself in which no object names a key twice. Only
// then does a part read alone read as it does in place: it cannot close what holds it, and
// the whole-file reader, which keeps the last of two equal keys, cannot see a later
// "objects" (or "chunks") that the parts read apart would miss.
bool selfContained(const std::string& text) {
    KeyRepeatFinder finder;
    return json::sax_parse(text, &finder) && !finder.repeated;
}

// The name on a chunk's first line (`   "chunk": "0000ffffo.chunk",`); std::nullopt when
// the line is not that.
std::optional<std::string> chunkName(const std::string& line) {
    const std::string key = kChunkName;
    if (line.size() <= key.size() || line.compare(0, key.size(), key) != 0 || line.back() != ',') return std::nullopt;
    const json name = json::parse(line.substr(key.size(), line.size() - key.size() - 1), nullptr, false);
    if (!name.is_string()) return std::nullopt;
    return name.get<std::string>();
}

// One object's text, "    {" to "    }", read by the whole-file reader's checks on an object
// (as one JSON value by itself: it cannot close what holds it in the file).
std::optional<ObjectRecord> parseObject(const std::string& path, const std::string& text) {
    Expected<ObjectRecord> object = parseObjectJson(path, text);
    if (!object) return std::nullopt;
    return std::move(*object);
}

// A reading in progress: the file, its current line and the chunk names seen. Each step
// gives true when it read its part, false when the file left the writer's layout (then the
// whole-file reader reads it), or the error that a part returned.
class LayoutReader {
public:
    LayoutReader(const std::string& path, const ChunkParts& parts) : path_(path), in_(path, std::ios::binary), parts_(parts) {}

    Expected<std::optional<ResultsFile>> read();

private:
    bool next() { return bool(std::getline(in_, line_)); }
    bool nextIs(const char* expected) { return next() && line_ == expected; }
    Expected<bool> readChunk(bool& more);
    Expected<bool> readObjects();

    const std::string& path_;
    std::ifstream in_;
    const ChunkParts& parts_;
    std::string line_;
    std::set<std::string> names_;
};

Expected<std::optional<ResultsFile>> LayoutReader::read() {
    const std::optional<ResultsFile> whole;  // "read it whole"
    if (!in_ || !nextIs("{") || !nextIs(kChunksOpen)) return whole;
    for (bool more = true; more;) {
        Expected<bool> chunk = readChunk(more);
        if (!chunk) return chunk.error();
        if (!*chunk) return whole;
    }
    // The rest: " ],", then the other keys; read as a file without chunks.
    if (!nextIs(kChunksClose)) return whole;
    const std::string rest = resultsHead() + "],\n" + std::string(std::istreambuf_iterator<char>(in_), {});
    if (in_.bad() || !selfContained(rest)) return whole;
    Expected<ResultsFile> f = parseResults(path_, rest);
    if (!f) return whole;
    return std::optional<ResultsFile>(std::move(*f));
}

// One chunk, "  {" to "  }" (`more`: it ended "  },", another follows).
Expected<bool> LayoutReader::readChunk(bool& more) {
    // 1. Its name, alone on the line after "  {" as the writer puts it first.
    if (!nextIs(kChunkOpen) || !next()) return false;
    const std::string nameLine = line_;
    const std::optional<std::string> name = chunkName(nameLine);
    // A chunk twice is the whole-file reader's error to give.
    if (!name || !names_.insert(*name).second) return false;
    if (parts_.begin)
        if (Status s = parts_.begin(*name); !s) return s.error();

    // 2. Its objects, each read alone; in the rest of the chunk they stand as `"objects": []`.
    std::string objectsLine = kObjectsNone;
    if (!next()) return false;
    if (line_ == kObjectsOpen) {
        Expected<bool> objects = readObjects();
        if (!objects || !*objects) return objects;
        if (line_ != kObjectsClose && line_ != kObjectsCloseMore) return false;
        if (line_ == kObjectsCloseMore) objectsLine += ",";
    } else if (line_ == objectsLine || line_ == objectsLine + ",") {
        objectsLine = line_;
    } else {
        return false;
    }

    // 3. The rest ("savings", "simulated"), read with an empty "objects" as a chunk.
    std::string rest = std::string(kChunkOpen) + "\n" + nameLine + "\n" + objectsLine + "\n";
    while (true) {
        if (!next()) return false;
        if (line_ == kChunkClose || line_ == kChunkCloseMore) break;
        rest += line_ + "\n";
    }
    rest += kChunkClose;
    more = line_ == kChunkCloseMore;
    if (!selfContained(rest)) return false;
    Expected<ChunkRecord> record = parseChunkJson(path_, rest);
    if (!record || record->chunk != *name || !record->objects.empty()) return false;
    if (parts_.end)
        if (Status s = parts_.end(*record); !s) return s.error();
    return true;
}

// The objects of a chunk after its `   "objects": [` line, up to the line that closes the
// array (left in line_).
Expected<bool> LayoutReader::readObjects() {
    std::string text;  // one object's, kept for the next one's (its capacity is the largest's)
    for (bool more = true; more;) {
        if (!nextIs(kObjectOpen)) return false;
        text = line_;
        while (true) {
            if (!next()) return false;
            if (line_ == kObjectClose || line_ == kObjectCloseMore) break;
            text += '\n';
            text += line_;
        }
        more = line_ == kObjectCloseMore;
        text += '\n';
        text += kObjectClose;
        std::optional<ObjectRecord> object = parseObject(path_, text);
        if (!object) return false;
        if (parts_.object)
            if (Status s = parts_.object(*object); !s) return s.error();
    }
    return next();
}

}  // namespace

Expected<std::optional<ResultsFile>> streamResultsFile(const std::string& path, const ChunkParts& parts) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || uint64_t(st.st_size) > (uint64_t(1) << 32))
        return std::optional<ResultsFile>();
    return LayoutReader(path, parts).read();
}

Expected<std::optional<ResultsFile>> streamResultsFile(const std::string& path, const ChunkVisitor& chunk) {
    ChunkRecord whole;
    ChunkParts parts;
    parts.begin = [&](const std::string& name) {
        whole = ChunkRecord{};
        whole.chunk = name;
        return Status::ok();
    };
    parts.object = [&](ObjectRecord& object) {
        whole.objects.push_back(std::move(object));
        return Status::ok();
    };
    parts.end = [&](ChunkRecord& rest) {
        whole.simulated = std::move(rest.simulated);
        whole.savings = std::move(rest.savings);
        return chunk(whole);
    };
    return streamResultsFile(path, parts);
}

}  // namespace shadowcull::results
