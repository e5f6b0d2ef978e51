// Wavefront OBJ + MTL loader. Written by hand rather than with a library so that group
// numbering follows the scene-format spec exactly and every error names file and line.

#include <algorithm>
#include <array>
#include <charconv>
#include <limits>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string_view>
#include <system_error>

#include "core/limits.h"
#include "core/mesh.h"
#include "io/file_read.h"
#include "io/mesh_load.h"
#include "util/format.h"

namespace fs = std::filesystem;

namespace shadowcull {
namespace {

// Thrown only inside this file and turned into an Error by loadObj; it keeps the small
// parsing helpers free of error plumbing.
struct ObjFailure {
    int line;
    std::string message;
};

[[noreturn]] void fail(int line, std::string message) { throw ObjFailure{line, std::move(message)}; }

// Text files only: a NUL byte means binary data (or a corrupt file), which would otherwise
// read as a file of unknown statements, that is as an empty mesh or material library.
void rejectBinary(const std::string& text) {
    if (size_t nul = text.find('\0'); nul != std::string::npos)
        fail(1 + int(std::count(text.begin(), text.begin() + std::ptrdiff_t(nul), '\n')),
             "binary data (a NUL byte): not a text file");
}

// Yields logical lines: physical lines ending in a backslash are joined with the next
// one, '\r' before '\n' is dropped and '#' starts a comment. A statement's line number is
// that of its first physical line, which is where an editor would take the user.
class LineReader {
public:
    explicit LineReader(const std::string& text) : text_(text) {}

    // The next statement, a view into the text (or, for a statement continued over several
    // physical lines, into a buffer held until the next call): no copy of every line.
    bool next(std::string_view& out, int& line) {
        if (pos_ >= text_.size()) return false;
        line = nextLine_;
        bool joined = false;
        while (pos_ < text_.size()) {
            size_t end = text_.find('\n', pos_);
            if (end == std::string::npos) end = text_.size();
            std::string_view phys(text_.data() + pos_, end - pos_);
            pos_ = end + 1;
            ++nextLine_;
            if (!phys.empty() && phys.back() == '\r') phys.remove_suffix(1);
            if (!phys.empty() && phys.back() == '\\') {
                if (!joined) joined_.clear(), joined = true;
                joined_.append(phys.data(), phys.size() - 1);
                joined_ += ' ';
                continue;
            }
            if (joined) joined_.append(phys.data(), phys.size());
            else out = phys;
            break;
        }
        if (joined) out = joined_;  // also when the text ends on a backslash
        if (size_t hash = out.find('#'); hash != std::string_view::npos) out = out.substr(0, hash);
        return true;
    }

private:
    const std::string& text_;
    std::string joined_;
    size_t pos_ = 0;
    int nextLine_ = 1;
};

// A table: splitting every line of a dense mesh into tokens was a fifth of its parse.
constexpr std::array<bool, 256> kBlank = [] {
    std::array<bool, 256> t{};
    for (unsigned char c : {' ', '\t', '\r', '\f', '\v'}) t[c] = true;
    return t;
}();
bool isBlank(char c) { return kBlank[static_cast<unsigned char>(c)]; }

void splitTokens(std::string_view s, std::vector<std::string_view>& out) {
    out.clear();
    size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && isBlank(s[i])) ++i;
        size_t start = i;
        while (i < s.size() && !isBlank(s[i])) ++i;
        if (i > start) out.push_back(s.substr(start, i - start));
    }
}

// The statement after its keyword, trimmed: material names may contain spaces.
std::string restAfter(std::string_view stmt, std::string_view keyword) {
    size_t b = size_t(keyword.data() - stmt.data()) + keyword.size();
    while (b < stmt.size() && isBlank(stmt[b])) ++b;
    size_t e = stmt.size();
    while (e > b && isBlank(stmt[e - 1])) --e;
    return std::string(stmt.substr(b, e - b));
}

std::string quoted(std::string_view s) { return "'" + std::string(s) + "'"; }

// from_chars is locale-independent and tells exactly where a number stops, so "1.5e" or
// "1.5x" (a truncated or corrupt file) is caught instead of silently read as 1.5.
double parseNumber(std::string_view tok, int line, double maxAbs = std::numeric_limits<double>::max()) {
    std::string_view s = tok;
    if (s.size() > 1 && s[0] == '+' && s[1] != '-') s.remove_prefix(1);  // from_chars rejects '+'
    double v = 0;
    auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec == std::errc::invalid_argument || ptr != s.data() + s.size()) fail(line, "malformed number " + quoted(tok));
    if (ec == std::errc::result_out_of_range) v = std::strtod(std::string(s).c_str(), nullptr);  // underflow is fine
    if (!std::isfinite(v)) fail(line, "non-finite number " + quoted(tok));
    if (std::abs(v) > maxAbs)
        fail(line, "number " + quoted(tok) + " is outside the accepted range " + formatInterval(-maxAbs, maxAbs) +
                       " (docs/format.md, accepted ranges)");
    return v;
}

// OBJ index (1-based, or negative = relative to the elements defined so far) -> 0-based.
uint32_t resolveIndex(std::string_view tok, std::string_view ref, size_t defined, const char* what, int line) {
    long long v = 0;
    auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (tok.empty() || ec != std::errc() || ptr != tok.data() + tok.size())
        fail(line, "malformed vertex reference " + quoted(ref));
    // Made only for a message: a string per reference was a fifth of parsing a dense mesh.
    auto where = [&] { return std::string(what) + " index " + std::string(tok) + (ref == tok ? "" : " in " + quoted(ref)); };
    if (v == 0) fail(line, where() + " is invalid (OBJ indices start at 1)");
    long long idx = v > 0 ? v - 1 : (long long)defined + v;
    if (idx < 0 || idx >= (long long)defined)
        fail(line, where() + " is out of range (" + std::to_string(defined) + " defined so far)");
    return uint32_t(idx);
}

// The two statements a dense mesh is made of, read in one pass without splitting them
// into tokens: "v x y z" and "f a b c" (plain positive indices, the group already open).
// Each returns false, having changed nothing, for anything it does not accept exactly as
// the general reading below would (other forms, signs, ranges, malformed or out-of-range
// values): that reading then takes the statement and gives its errors. A fifth of a dense
// world's scan was splitting and re-checking such lines.
//
// The next number of `s` from `at` (after blanks), ending at a blank or the end.
template <class T>
bool nextNumber(std::string_view s, size_t& at, T& value) {
    while (at < s.size() && isBlank(s[at])) ++at;
    if (at == s.size() || s[at] == '+') return false;  // '+': the general reading strips it
    const auto [ptr, ec] = std::from_chars(s.data() + at, s.data() + s.size(), value);
    if (ec != std::errc() || ptr == s.data() + at) return false;
    at = size_t(ptr - s.data());
    return at == s.size() || isBlank(s[at]);
}

bool onlyBlanksFrom(std::string_view s, size_t at) {
    while (at < s.size() && isBlank(s[at])) ++at;
    return at == s.size();
}

bool readPlainVertex(std::string_view stmt, std::vector<glm::dvec3>& positions) {
    size_t at = 1;
    glm::dvec3 p;
    for (int k = 0; k < 3; ++k)
        if (!nextNumber(stmt, at, p[k]) || !std::isfinite(p[k]) || std::abs(p[k]) > limits::kMaxLocalCoordinate) return false;
    if (!onlyBlanksFrom(stmt, at) || positions.size() >= UINT32_MAX) return false;
    positions.push_back(p);
    return true;
}

bool readPlainTriangle(std::string_view stmt, Mesh& mesh, uint32_t group) {
    size_t at = 1;
    std::array<uint32_t, 3> tri;
    for (uint32_t& v : tri) {
        long long index = 0;
        if (!nextNumber(stmt, at, index) || index < 1 || index > (long long)mesh.positions.size()) return false;
        v = uint32_t(index - 1);
    }
    if (!onlyBlanksFrom(stmt, at)) return false;
    mesh.triangles.push_back(tri);
    mesh.triangleGroup.push_back(group);
    return true;
}

// A material library as far as the bake needs it: the materials it defines, and those with
// a `map_d` (the spec's only alpha-test signal; a `d` < 1 alone means blending and is
// deliberately ignored).
struct Materials {
    std::set<std::string> defined, alphaTested;
};

// Reads one MTL file. A library that is missing, unreadable or broken is an error, never
// skipped: without it alpha-tested foliage would bake as opaque and cull shadows the engine
// draws. Errors thrown here carry the MTL's own line; loadObj names the MTL file.
struct MtlFailure {
    std::string file;
    int line;
    std::string message;
};

void readMtl(const fs::path& path, int mtllibLine, Materials& out) {
    Expected<std::string> text = readRegularFile(path.string(), "material library");
    if (!text) fail(mtllibLine, "mtllib " + quoted(std::string_view(path.filename().string())) + ": " + text.error().message);
    try {
        rejectBinary(*text);
        LineReader reader(*text);
        std::string_view stmt;
        std::string material;
        bool inMaterial = false;
        int line = 0;
        std::vector<std::string_view> tok;
        while (reader.next(stmt, line)) {
            splitTokens(stmt, tok);
            if (tok.empty()) continue;
            if (tok[0] == "newmtl") {
                material = restAfter(stmt, tok[0]);
                if (material.empty()) fail(line, "'newmtl' needs a material name");
                out.defined.insert(material);
                inMaterial = true;
            } else if (tok[0] == "map_d") {
                if (!inMaterial) fail(line, "'map_d' before any 'newmtl'");
                if (tok.size() < 2) fail(line, "'map_d' needs a texture file");
                out.alphaTested.insert(material);
            }
        }
    } catch (const ObjFailure& f) {
        throw MtlFailure{path.string(), f.line, f.message};
    }
}

Mesh parseObj(const fs::path& path, const std::string& text) {
    Mesh mesh;
    std::map<std::string, uint32_t> groupIndex;
    // Group numbering (spec: one group per material in order of first use). A `usemtl`
    // creates its group at once, even if no face follows, so numbering depends only on the
    // order of `usemtl` lines. Faces before the first `usemtl` go to a group named "" that
    // is created at the first such face; it therefore gets number 0 whenever it exists,
    // which also makes a file without any `usemtl` group 0, as the spec requires. A bare
    // `usemtl` (no name) selects that same "" group.
    auto groupFor = [&](const std::string& name) {
        auto [it, added] = groupIndex.emplace(name, uint32_t(mesh.groups.size()));
        if (added) mesh.groups.push_back(PrimitiveGroup{name, false, false, std::nullopt});
        return it->second;
    };
    std::vector<std::pair<fs::path, int>> mtlFiles;  // library, line of its `mtllib`
    std::map<std::string, int> usedAt;                // material -> line of its first `usemtl`
    size_t texcoords = 0, normals = 0;
    bool haveGroup = false;
    uint32_t group = 0;

    // Room for every vertex and (triangular) face up front, counted by the lines' first
    // letters (an estimate: continued lines and polygons are rare): growing the arrays as
    // they fill touched about twice a dense mesh's size in fresh pages, copies included.
    {
        size_t vertices = 0, faces = 0;
        for (size_t at = 0; at + 1 < text.size();) {
            vertices += text[at] == 'v' && isBlank(text[at + 1]);
            faces += text[at] == 'f' && isBlank(text[at + 1]);
            const size_t end = text.find('\n', at);
            if (end == std::string::npos) break;
            at = end + 1;
        }
        mesh.positions.reserve(vertices);
        mesh.triangles.reserve(faces);
        mesh.triangleGroup.reserve(faces);
    }
    LineReader reader(text);
    std::string_view stmt;
    int line = 0;
    std::vector<std::string_view> tok;
    std::vector<uint32_t> poly;
    while (reader.next(stmt, line)) {
        if (stmt.size() > 2 && isBlank(stmt[1]) &&
            ((stmt[0] == 'v' && readPlainVertex(stmt, mesh.positions)) ||
             (stmt[0] == 'f' && haveGroup && readPlainTriangle(stmt, mesh, group))))
            continue;
        splitTokens(stmt, tok);
        if (tok.empty()) continue;
        const std::string_view key = tok[0];
        if (key == "v") {
            // x y z, optionally w or an r g b colour (a common extension); only xyz is used,
            // but every value must be a number so truncation is noticed.
            if (tok.size() < 4 || tok.size() > 7) fail(line, "'v' needs x y z [w] (or x y z r g b)");
            const double m = limits::kMaxLocalCoordinate;
            glm::dvec3 p(parseNumber(tok[1], line, m), parseNumber(tok[2], line, m), parseNumber(tok[3], line, m));
            for (size_t k = 4; k < tok.size(); ++k) parseNumber(tok[k], line);
            if (mesh.positions.size() >= UINT32_MAX) fail(line, "too many vertices for 32-bit indices");
            mesh.positions.push_back(p);
        } else if (key == "vt") {
            ++texcoords;  // counted only to range-check face references
        } else if (key == "vn") {
            ++normals;
        } else if (key == "f") {
            if (tok.size() < 4) fail(line, "a face needs at least 3 vertices");
            poly.clear();
            for (size_t k = 1; k < tok.size(); ++k) {
                // v, v/vt, v//vn or v/vt/vn.
                std::string_view ref = tok[k], parts[3];
                size_t n = 0, start = 0;
                for (size_t i = 0; i <= ref.size(); ++i) {
                    if (i < ref.size() && ref[i] != '/') continue;
                    if (n == 3) fail(line, "malformed vertex reference " + quoted(ref));
                    parts[n++] = ref.substr(start, i - start);
                    start = i + 1;
                }
                poly.push_back(resolveIndex(parts[0], ref, mesh.positions.size(), "vertex", line));
                if (n >= 2 && !(n == 3 && parts[1].empty()))
                    resolveIndex(parts[1], ref, texcoords, "texture coordinate", line);
                if (n == 3) resolveIndex(parts[2], ref, normals, "normal", line);
            }
            if (!haveGroup) {
                group = groupFor("");
                haveGroup = true;
            }
            // Fan around the first vertex keeps the polygon's winding in every triangle.
            for (size_t k = 1; k + 1 < poly.size(); ++k) {
                mesh.triangles.push_back({poly[0], poly[k], poly[k + 1]});
                mesh.triangleGroup.push_back(group);
            }
        } else if (key == "usemtl") {
            const std::string name = restAfter(stmt, key);
            group = groupFor(name);
            usedAt.emplace(name, line);
            haveGroup = true;
        } else if (key == "mtllib") {
            // Names are space-separated, but accept a single name with spaces if it exists.
            const fs::path dir = path.parent_path();
            std::error_code ec;
            if (tok.size() < 2) fail(line, "'mtllib' needs a file name");
            if (std::string whole = restAfter(stmt, key); fs::is_regular_file(dir / whole, ec)) {
                mtlFiles.emplace_back(dir / whole, line);
            } else {
                for (size_t k = 1; k < tok.size(); ++k) mtlFiles.emplace_back(dir / std::string(tok[k]), line);
            }
        }
        // Everything else (o, g, s, l, p, vp, curves, ...) does not affect the triangles.
    }

    if (mesh.groups.empty()) groupFor("");  // no faces and no usemtl: still one group
    Materials materials;
    for (const auto& [mtl, mtllibLine] : mtlFiles) {
        readMtl(mtl, mtllibLine, materials);
        mesh.sourceFiles.push_back(mtl.string());
    }
    // A material the libraries do not define has unknown alpha: the group is marked, and
    // loading its model fails unless a .model override decides (never a guess of opaque).
    // A bare `usemtl`, the "" group, names no material.
    for (PrimitiveGroup& g : mesh.groups) {
        g.alphaTested = materials.alphaTested.count(g.name) > 0;
        if (!g.name.empty() && !materials.defined.count(g.name))
            g.alphaUnknown = makeError(
                ErrorKind::BadInput, path.string(), usedAt.at(g.name),
                "material " + quoted(std::string_view(g.name)) + " is not defined" +
                    (mtlFiles.empty() ? " (the file names no material library, 'mtllib')"
                                      : " in the material libraries the file names") +
                    ", so whether it is alpha-tested is unknown (a .model <primitiveGroup alphaTest=...> decides it)");
    }
    return mesh;
}

}  // namespace

Expected<Mesh> loadObj(const std::string& path) {
    Expected<std::string> text = readRegularFile(path, "OBJ file");
    if (!text) return text.error();
    try {
        rejectBinary(*text);
        Mesh mesh = parseObj(path, *text);
        mesh.sourceFiles.insert(mesh.sourceFiles.begin(), path);
        return mesh;
    } catch (const ObjFailure& f) {
        return makeError(ErrorKind::BadInput, path, f.line, f.message);
    } catch (const MtlFailure& f) {
        return makeError(ErrorKind::BadInput, f.file, f.line, f.message + " (material library of " + path + ")");
    }
}

}  // namespace shadowcull
