// glTF 2.0 documents: container (.gltf/.glb), buffers, accessors, node forest and mesh
// decoding (io/gltf_document.h). Only what shadow culling needs is decoded; every range
// is checked against the real data so that a truncated or inconsistent file is an error
// naming the file and the JSON path, never a wrong mesh.
//
// Read as real pipelines write it: KHR_mesh_quantization (integer positions, normalized
// or not), sparse accessors, EXT_meshopt_compression buffer views (decoded by Debian's
// libmeshoptimizer, once per view) and KHR_draco_mesh_compression primitives (decoded by
// Debian's libdraco). The compressed formats are decoded by their reference libraries;
// everything around them (ranges, counts, strides, modes) is checked here first, since
// both libraries assert or trust their arguments.

#include "io/gltf_document.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <new>
#include <optional>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <nlohmann/json.hpp>

#include "core/limits.h"
#include "io/file_read.h"
#include "io/gltf_codecs.h"
#include "util/format.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace shadowcull {
namespace {

using gltf_codecs::component;
using gltf_codecs::componentSize;
using gltf_codecs::decodeBase64;
using gltf_codecs::percentDecode;
using gltf_codecs::readFloat;
using gltf_codecs::readUint;

// Thrown only inside this file and turned into an Error by the public methods: validation
// is deeply nested and an exception keeps each check to one line.
struct GltfFailure {
    ErrorKind kind;
    int line;
    std::string message;
};

[[noreturn]] void fail(std::string message, ErrorKind kind = ErrorKind::BadInput, int line = 0) {
    throw GltfFailure{kind, line, std::move(message)};
}

// A regular file only (io/file_read.h: a FIFO or directory is refused, never waited on).
void readFile(const fs::path& path, const std::string& what, std::vector<uint8_t>& out) {
    Expected<std::string> text = readRegularFile(path.string(), what);
    if (!text) fail(what + " '" + path.string() + "': " + text.error().message, text.error().kind);
    out.assign(text->begin(), text->end());
}

std::string at(const std::string& array, size_t i) { return gltfPath(array, i); }

std::string integerComponentName(uint64_t componentType) {
    switch (componentType) {
        case 5120: return "BYTE";
        case 5121: return "UNSIGNED_BYTE";
        case 5122: return "SHORT";
        case 5123: return "UNSIGNED_SHORT";
        case 5125: return "UNSIGNED_INT";
        default: return "not an integer type";
    }
}

const json* member(const json& obj, const char* key) {
    auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
}

uint64_t uintField(const json& obj, const char* key, const std::string& where, std::optional<uint64_t> def = {}) {
    const json* v = member(obj, key);
    if (!v) {
        if (!def) fail(where + ": '" + key + "' is missing");
        return *def;
    }
    if (!v->is_number_unsigned()) fail(where + "." + key + ": non-negative integer expected");
    return v->get<uint64_t>();
}

// Array `key` of exactly `n` finite numbers.
std::vector<double> numbers(const json& obj, const char* key, const std::string& where, size_t n) {
    const json& v = obj[key];
    if (!v.is_array() || v.size() != n) fail(where + "." + key + ": array of " + std::to_string(n) + " numbers expected");
    std::vector<double> out;
    for (const json& x : v) {
        if (!x.is_number() || !std::isfinite(x.get<double>()))
            fail(where + "." + key + ": array of " + std::to_string(n) + " finite numbers expected");
        out.push_back(x.get<double>());
    }
    return out;
}

// A column-major glTF `matrix`. glTF allows it or TRS, never both, and only an affine one:
// with TRS beside it, or a last row other than 0 0 0 1, which placement was meant is not
// known, so neither is guessed (the row would be dropped, or the TRS).
glm::dmat4 matrixTransform(const json& node, const std::string& where) {
    for (const char* trs : {"translation", "rotation", "scale"})
        if (member(node, trs))
            fail(where + ": both matrix and " + trs + " (glTF allows one or the other; which placement was meant is not known)");
    const std::vector<double> v = numbers(node, "matrix", where, 16);
    glm::dmat4 m(1.0);
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) m[c][r] = v[size_t(c * 4 + r)];
    if (m[0][3] != 0 || m[1][3] != 0 || m[2][3] != 0 || m[3][3] != 1)
        fail(where + ".matrix: elements 3, 7, 11 and 15 (the last row) are " + formatNumber(m[0][3]) + " " +
             formatNumber(m[1][3]) + " " + formatNumber(m[2][3]) + " " + formatNumber(m[3][3]) +
             ", not 0 0 0 1 (a node matrix must be affine)");
    return m;
}

// The node's `matrix`, or the product T * R * S of its TRS properties.
glm::dmat4 localTransform(const json& node, const std::string& where) {
    if (member(node, "matrix")) return matrixTransform(node, where);
    glm::dmat4 m(1.0);
    if (member(node, "translation")) {
        std::vector<double> t = numbers(node, "translation", where, 3);
        m = glm::translate(m, glm::dvec3(t[0], t[1], t[2]));
    }
    if (member(node, "rotation")) {
        std::vector<double> q = numbers(node, "rotation", where, 4);  // x, y, z, w
        glm::dquat rot(q[3], q[0], q[1], q[2]);
        // Exporters write unit quaternions rounded to float; normalise so rounding does not
        // scale the model, but a zero quaternion has no rotation to recover.
        if (!(glm::length(rot) > 1e-12)) fail(where + ".rotation: zero quaternion");
        m *= glm::mat4_cast(glm::normalize(rot));
    }
    if (member(node, "scale")) {
        std::vector<double> s = numbers(node, "scale", where, 3);
        m = glm::scale(m, glm::dvec3(s[0], s[1], s[2]));
    }
    return m;
}

// An accessor resolved to bytes; `data` is null for an accessor without bufferView, whose
// elements are all zero by the glTF spec. `data` points into a buffer, into a decoded
// EXT_meshopt_compression view (both owned by the document), or into `owned` (a sparse
// accessor, applied to a copy of its base).
struct AccessorView {
    std::string where;
    uint64_t componentType = 0;
    bool normalized = false;
    std::string type;
    size_t count = 0;
    size_t stride = 0;
    const uint8_t* data = nullptr;
    std::shared_ptr<const std::vector<uint8_t>> owned;
};

// A buffer view's bytes: a range of its buffer, or what its EXT_meshopt_compression data
// decodes to. `stride` is the view's byteStride when it has one.
struct ViewBytes {
    const uint8_t* data = nullptr;
    uint64_t length = 0;
    std::optional<uint64_t> stride;
    std::string origin;        // for messages: "buffers[0]", or "the data decoded from ..."
    uint64_t originOffset = 0;  // the view's byteOffset in `origin`
    std::string describe(uint64_t offset) const {
        return "byte offset " + std::to_string(originOffset + offset) + " of " + origin;
    }
};

// The largest ratio of decoded to compressed bytes that EXT_meshopt_compression can reach:
// the attribute codec spends at least 2 header bits on every 16 bytes of a byte channel
// (a group of zero deltas), so 64:1 at best; the index codecs spend at least a byte per
// triangle or per index (12:1, 4:1). A view that claims more is corrupt or hostile.
constexpr uint64_t kMeshoptMaxRatio = 64;

// Extensions a file may require: those read where they occur (positions, compression,
// lights), and those that only change how texture images are stored or mapped (no image
// is read: alpha testing comes from alphaMode alone).
constexpr const char* kHonouredExtensions[] = {
    "KHR_mesh_quantization", "EXT_meshopt_compression", "KHR_draco_mesh_compression", "KHR_lights_punctual",
    "KHR_texture_basisu",    "EXT_texture_webp",        "EXT_texture_avif",           "KHR_texture_transform"};


}  // namespace

std::string gltfPath(const std::string& array, size_t index) { return array + "[" + std::to_string(index) + "]"; }

struct GltfDocument::Impl {
    using json = nlohmann::json;  // the enclosing class has a member function named json

    std::string path;
    json doc;
    bool isGlb = false;
    std::optional<std::vector<uint8_t>> bin;
    std::vector<std::optional<std::vector<uint8_t>>> buffers;
    std::vector<GltfNode> nodes;
    std::vector<std::optional<std::vector<GltfPrimitive>>> meshes;  // decoded on first use
    std::vector<std::string> sourceFiles;
    std::vector<Diagnostic> warnings;
    // EXT_meshopt_compression views by index, decoded on first use (map: stable references).
    std::map<uint64_t, std::vector<uint8_t>> decodedViews;
    uint64_t bufferBytes = 0;   // bytes of the buffers read so far
    uint64_t decodedBytes = 0;  // bytes of decodedViews
    uint64_t fileBytes = 0;     // bytes of the .gltf/.glb itself
    // Vertices and indices decoded so far, over every primitive. Each primitive decodes its
    // accessors anew, so a small file whose thousand primitives all name one big accessor
    // (or one of 2^24 zeros without bufferView) would otherwise ask for a copy each:
    // hundreds of gigabytes from kilobytes. A real file decodes at most about 64 elements
    // per byte it holds (meshopt's best ratio; a byte per index), so more than that is
    // refused as corrupt or hostile.
    uint64_t decodedElements = 0;
    void spend(uint64_t elements, const std::string& where) {
        const uint64_t budget = 64 * (fileBytes + bufferBytes) + (uint64_t(1) << 24);
        decodedElements += elements;
        if (decodedElements > budget)
            fail(where + ": decoding would give " + std::to_string(decodedElements) + " vertices and indices from " +
                 std::to_string(fileBytes + bufferBytes) +
                 " bytes of file and buffers, more than 64 per byte (accessors shared by many primitives, or a "
                 "corrupt count)");
    }

    void open() {
        readContainer();
        if (!doc.is_object()) fail("the JSON top level must be an object");
        if (const json* asset = member(doc, "asset"); asset && asset->is_object()) {
            const json* version = member(*asset, "version");
            if (version && version->is_string() && version->get<std::string>().rfind("2.", 0) != 0)
                fail("asset.version: glTF " + version->get<std::string>() + " is not supported (2.x expected)");
        }
        checkRequiredExtensions();
        buffers.resize(array("buffers").size());  // before any buffer() hands out references
        meshes.resize(array("meshes").size());
        readNodes();
    }

    // A reader must refuse a file whose required extension it does not implement: read
    // without it, the file means something else (instanced nodes drawn once, materials
    // switched, positions of another encoding).
    void checkRequiredExtensions() const {
        const json* required = member(doc, "extensionsRequired");
        if (!required) return;
        if (!required->is_array()) fail("extensionsRequired: array of strings expected");
        for (size_t i = 0; i < required->size(); ++i) {
            const json& name = (*required)[i];
            if (!name.is_string()) fail(at("extensionsRequired", i) + ": string expected");
            const auto& known = kHonouredExtensions;
            if (std::find(std::begin(known), std::end(known), name.get<std::string>()) == std::end(known))
                fail(at("extensionsRequired", i) + ": '" + name.get<std::string>() +
                     "' is required, and this reader does not implement it (it implements KHR_mesh_quantization, "
                     "EXT_meshopt_compression, KHR_draco_mesh_compression and KHR_lights_punctual, and reads no "
                     "texture, so texture formats and transforms may be required too)");
        }
    }

    // Whether the file declares extension `name` (extensionsUsed lists every one it uses,
    // extensionsRequired those it cannot be read without).
    bool declares(const char* name) const {
        for (const char* list : {"extensionsUsed", "extensionsRequired"})
            if (const json* l = member(doc, list); l && l->is_array() && std::find(l->begin(), l->end(), name) != l->end())
                return true;
        return false;
    }

    const json& array(const char* name) const {
        static const json empty = json::array();
        const json* a = member(doc, name);
        if (!a) return empty;
        if (!a->is_array()) fail(std::string(name) + ": array expected");
        return *a;
    }

    // Element `i` of top-level array `name`, referenced from `referrer`.
    const json& element(const char* name, uint64_t i, const std::string& referrer) const {
        const json& a = array(name);
        if (i >= a.size())
            fail(referrer + ": " + at(name, i) + " does not exist (" + std::to_string(a.size()) + " defined)");
        if (!a[i].is_object()) fail(at(name, i) + ": object expected");
        return a[i];
    }

    void readContainer() {
        std::vector<uint8_t> bytes;
        readFile(path, "glTF file", bytes);
        fileBytes = bytes.size();
        std::string text;
        if (bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0) {
            isGlb = true;
            readGlb(bytes, text);
        } else {
            std::string ext = fs::path(path).extension().string();
            std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
            if (ext == ".glb") fail("byte offset 0: not a GLB file (no 'glTF' magic; truncated?)");
            text.assign(bytes.begin(), bytes.end());
        }
        try {
            doc = json::parse(text);
        } catch (const json::parse_error& e) {
            // e.byte counts the bytes read including the offending one; the line is that of
            // the offending byte (nlohmann would put a stray newline in a string on the next
            // line, so its own "at line N, column M" is dropped from the message).
            size_t pos = std::min(e.byte > 0 ? size_t(e.byte - 1) : 0, text.size());
            int line = 1 + int(std::count(text.begin(), text.begin() + std::ptrdiff_t(pos), '\n'));
            std::string what = e.what();
            if (size_t colon = what.find(": "); colon != std::string::npos) what = what.substr(colon + 2);
            if (isGlb) fail("JSON chunk line " + std::to_string(line) + ": " + what);
            fail("JSON " + what, ErrorKind::BadInput, line);
        }
    }

    void readGlb(const std::vector<uint8_t>& bytes, std::string& text) {
        const size_t size = bytes.size();
        if (size < 12) fail("GLB header is truncated (" + std::to_string(size) + " bytes)");
        if (uint32_t version = readUint(&bytes[4], 4); version != 2)
            fail("byte offset 4: GLB version " + std::to_string(version) + " is not supported (2 expected)");
        const size_t length = readUint(&bytes[8], 4);
        if (length > size)
            fail("byte offset 8: GLB length is " + std::to_string(length) + " bytes but the file has " +
                 std::to_string(size) + " (truncated)");
        bool first = true;
        for (size_t offset = 12; offset < length;) {
            if (length - offset < 8) fail("byte offset " + std::to_string(offset) + ": truncated GLB chunk header");
            const size_t chunkLength = readUint(&bytes[offset], 4), type = readUint(&bytes[offset + 4], 4);
            if (chunkLength > length - offset - 8)
                fail("byte offset " + std::to_string(offset) + ": GLB chunk of " + std::to_string(chunkLength) +
                     " bytes runs past the end of the file (truncated)");
            const uint8_t* data = bytes.data() + offset + 8;
            if (first && type != 0x4E4F534A) fail("byte offset 12: the first GLB chunk must be JSON");
            if (first) text.assign(data, data + chunkLength);
            if (!first && type == 0x004E4942 && !bin) bin.emplace(data, data + chunkLength);
            first = false;  // other chunk types are extensions' business
            offset += 8 + chunkLength;
        }
        if (first) fail("byte offset 12: GLB has no JSON chunk");
    }

    const std::vector<uint8_t>& buffer(uint64_t i, const std::string& referrer) {
        const json& b = element("buffers", i, referrer);
        if (buffers[i]) return *buffers[i];
        const std::string where = at("buffers", i);
        // A placeholder for the uncompressed data of EXT_meshopt_compression views: never
        // read (it usually has no data at all), and only compressed views may name it.
        if (const json* ext = member(b, "extensions"); ext && ext->is_object())
            if (const json* mo = member(*ext, "EXT_meshopt_compression"); mo && mo->is_object())
                if (const json* fallback = member(*mo, "fallback"); fallback && *fallback == true)
                    fail(referrer + ": " + where + " is an EXT_meshopt_compression fallback buffer, which only " +
                         "compressed buffer views may name (as the buffer of their uncompressed data)");
        const uint64_t byteLength = uintField(b, "byteLength", where);
        std::vector<uint8_t> data;
        const json* uriField = member(b, "uri");
        if (!uriField) {
            if (i != 0 || !bin) fail(where + ": no uri and no GLB BIN chunk");
            data = std::move(*bin);
        } else {
            if (!uriField->is_string()) fail(where + ".uri: string expected");
            const std::string uri = uriField->get<std::string>();
            if (uri.rfind("data:", 0) == 0) {
                // data:application/octet-stream;base64,... (or gltf-buffer, or any media type).
                const size_t comma = uri.find(',');
                if (comma == std::string::npos || comma < 12 || uri.compare(comma - 7, 7, ";base64") != 0)
                    fail(where + ".uri: only base64 data: URIs are supported");
                if (!decodeBase64(std::string_view(uri).substr(comma + 1), data))
                    fail(where + ".uri: invalid base64 data");
            } else if (uri.find("://") != std::string::npos) {
                fail(where + ".uri: remote buffer '" + uri + "' is not supported");
            } else {
                // A scene names files beside it or below: an absolute path or one that climbs
                // out (../) could make a bake read any file (/etc/passwd as a buffer).
                const fs::path relative = fs::path(percentDecode(uri)).lexically_normal();
                if (relative.is_absolute() || relative.has_root_name() || relative.has_root_directory() ||
                    (!relative.empty() && *relative.begin() == ".."))
                    fail(where + ".uri: '" + uri + "' lies outside the scene's directory; buffer files are read only "
                         "from the scene's directory or below it");
                const fs::path file = fs::path(path).parent_path() / relative;
                readFile(file, where + ": buffer file", data);
                sourceFiles.push_back(file.string());
            }
        }
        if (data.size() < byteLength)
            fail(where + ": byteLength is " + std::to_string(byteLength) + " but only " + std::to_string(data.size()) +
                 " bytes are present (truncated)");
        data.resize(size_t(byteLength));  // GLB padding is not part of the buffer
        bufferBytes += data.size();
        buffers[i] = std::move(data);
        return *buffers[i];
    }

    // Buffer view `view`'s bytes, decoded from EXT_meshopt_compression if it has that.
    ViewBytes bufferView(uint64_t view, const std::string& referrer) {
        const std::string where = at("bufferViews", view);
        const json& bv = element("bufferViews", view, referrer);
        ViewBytes out;
        out.length = uintField(bv, "byteLength", where);
        if (member(bv, "byteStride")) out.stride = uintField(bv, "byteStride", where);
        if (const json* ext = member(bv, "extensions"); ext && ext->is_object()) {
            if (const json* mo = member(*ext, "EXT_meshopt_compression")) {
                out.data = meshoptView(view, bv, *mo, where, out.length).data();
                out.origin = "the data decoded from " + where + ".extensions.EXT_meshopt_compression";
                return out;
            }
            if (member(*ext, "MESHOPT_compression"))
                fail(where + ": MESHOPT_compression (the draft of EXT_meshopt_compression) is not supported; " +
                     "re-export with gltfpack 0.15 or later");
        }
        const uint64_t offset = uintField(bv, "byteOffset", where, 0);
        const uint64_t b = uintField(bv, "buffer", where);
        const std::vector<uint8_t>& buf = buffer(b, where);
        if (offset > buf.size() || out.length > buf.size() - offset)
            fail(where + ": bytes " + std::to_string(offset) + ".." + std::to_string(offset + out.length) +
                 " lie outside its buffer of " + std::to_string(buf.size()) + " bytes (truncated)");
        out.data = buf.data() + offset;
        out.origin = at("buffers", b);
        out.originOffset = offset;
        return out;
    }

    // EXT_meshopt_compression: the view's bytes decoded by libmeshoptimizer, once. Every
    // constraint of the extension's spec is checked first (the library asserts them).
    const std::vector<uint8_t>& meshoptView(uint64_t view, const json& bv, const json& ext, const std::string& where,
                                            uint64_t viewLength) {
        if (auto done = decodedViews.find(view); done != decodedViews.end()) return done->second;
        const std::string ew = where + ".extensions.EXT_meshopt_compression";
        if (!ext.is_object()) fail(ew + ": object expected");
        const uint64_t count = uintField(ext, "count", ew);
        const uint64_t stride = uintField(ext, "byteStride", ew);
        const json* modeField = member(ext, "mode");
        if (!modeField || !modeField->is_string()) fail(ew + ".mode: ATTRIBUTES, TRIANGLES or INDICES expected");
        const std::string mode = modeField->get<std::string>();
        if (mode != "ATTRIBUTES" && mode != "TRIANGLES" && mode != "INDICES")
            fail(ew + ".mode: '" + mode + "' is not ATTRIBUTES, TRIANGLES or INDICES");
        std::string filter = "NONE";
        if (const json* f = member(ext, "filter")) {
            if (!f->is_string()) fail(ew + ".filter: NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL expected");
            filter = f->get<std::string>();
        }
        if (filter != "NONE" && filter != "OCTAHEDRAL" && filter != "QUATERNION" && filter != "EXPONENTIAL")
            fail(ew + ".filter: '" + filter + "' is not NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL");
        if (mode == "ATTRIBUTES" && (stride == 0 || stride % 4 != 0 || stride > 256))
            fail(ew + ".byteStride: " + std::to_string(stride) + " (ATTRIBUTES needs a multiple of 4, at most 256)");
        if (mode != "ATTRIBUTES" && stride != 2 && stride != 4)
            fail(ew + ".byteStride: " + std::to_string(stride) + " (" + mode + " needs 2 or 4)");
        if (mode == "TRIANGLES" && count % 3 != 0)
            fail(ew + ".count: " + std::to_string(count) + " indices do not make whole triangles");
        if (mode != "ATTRIBUTES" && filter != "NONE") fail(ew + ".filter: " + filter + " with mode " + mode + " (only NONE)");
        if ((filter == "OCTAHEDRAL" && stride != 4 && stride != 8) || (filter == "QUATERNION" && stride != 8))
            fail(ew + ".byteStride: " + std::to_string(stride) + " does not suit filter " + filter +
                 (filter == "QUATERNION" ? " (8 expected)" : " (4 or 8 expected)"));
        if (const json* parentStride = member(bv, "byteStride"); parentStride && *parentStride != stride)
            fail(where + ".byteStride: " + parentStride->dump() + " differs from the extension's byteStride " +
                 std::to_string(stride));
        // count is bounded by the view length before the product is formed (stride <= 256).
        if (count > viewLength || count * stride != viewLength)
            fail(ew + ": count " + std::to_string(count) + " x byteStride " + std::to_string(stride) + " is not " +
                 where + ".byteLength " + std::to_string(viewLength));

        const uint64_t b = uintField(ext, "buffer", ew);
        const uint64_t offset = uintField(ext, "byteOffset", ew, 0);
        const uint64_t length = uintField(ext, "byteLength", ew);
        const std::vector<uint8_t>& buf = buffer(b, ew);
        if (offset > buf.size() || length > buf.size() - offset)
            fail(ew + ": bytes " + std::to_string(offset) + ".." + std::to_string(offset + length) + " lie outside " +
                 at("buffers", b) + " of " + std::to_string(buf.size()) + " bytes (truncated)");
        // Decoded-size bound: no valid stream decodes to more than kMeshoptMaxRatio times its
        // compressed length, so a view that claims more is refused before anything is
        // allocated; and the views decoded so far together stay within that ratio of all
        // the buffer bytes read, so that many views naming the same compressed bytes cannot
        // add up either. Memory is thus at most 64 times the input's size.
        if (viewLength > kMeshoptMaxRatio * length)
            fail(ew + ": " + std::to_string(count) + " elements of " + std::to_string(stride) + " bytes (" +
                 std::to_string(viewLength) + " bytes) cannot come from " + std::to_string(length) +
                 " compressed bytes (at most " + std::to_string(kMeshoptMaxRatio) + " times as many; corrupt?)");
        if (decodedBytes + viewLength > kMeshoptMaxRatio * bufferBytes)
            fail(ew + ": with its " + std::to_string(viewLength) + " bytes the decoded views would hold " +
                 std::to_string(decodedBytes + viewLength) + " bytes, more than " + std::to_string(kMeshoptMaxRatio) +
                 " times the " + std::to_string(bufferBytes) + " buffer bytes read (views sharing compressed bytes?)");

        std::vector<uint8_t> out;
        if (const int rc = gltf_codecs::decodeMeshopt(mode, filter, count, stride, buf.data() + offset, length, out); rc != 0)
            fail(ew + ": the compressed " + mode + " data (" + std::to_string(length) + " bytes at byte offset " +
                 std::to_string(offset) + " of " + at("buffers", b) + ") does not decode (meshoptimizer error " +
                 std::to_string(rc) + "; truncated or corrupt)");
        decodedBytes += viewLength;
        return decodedViews.emplace(view, std::move(out)).first->second;
    }

    AccessorView accessor(uint64_t i, const std::string& referrer) {
        AccessorView v;
        v.where = at("accessors", i);
        const json& a = element("accessors", i, referrer);
        v.componentType = uintField(a, "componentType", v.where);
        const size_t compSize = componentSize(v.componentType);
        if (!compSize) fail(v.where + ".componentType: unknown value " + std::to_string(v.componentType));
        if (const json* normalized = member(a, "normalized")) {
            if (!normalized->is_boolean()) fail(v.where + ".normalized: true or false expected");
            v.normalized = normalized->get<bool>();
            if (v.normalized && compSize == 4)
                fail(v.where + ".normalized: only BYTE, UNSIGNED_BYTE, SHORT and UNSIGNED_SHORT components can be normalized");
        }
        const json* type = member(a, "type");
        if (!type || !type->is_string()) fail(v.where + ".type: string expected");
        v.type = type->get<std::string>();
        const uint64_t count = uintField(a, "count", v.where);
        const size_t components = v.type == "SCALAR" ? 1 : v.type == "VEC2" ? 2 : v.type == "VEC3" ? 3 : v.type == "VEC4" ? 4 : 0;
        if (!components) fail(v.where + ".type: '" + v.type + "' is not SCALAR or VECn");
        const size_t elementSize = compSize * components;
        const json* viewIndex = member(a, "bufferView");
        if (!viewIndex) {
            // All-zero data (unless sparse substitutes some): legitimate only in small
            // amounts, so a huge count means corruption (and must not become a huge allocation).
            if (count > (uint64_t(1) << 24)) fail(v.where + ": count " + std::to_string(count) + " without bufferView");
            v.count = size_t(count);
        } else {
            const uint64_t view = uintField(a, "bufferView", v.where);
            const std::string viewWhere = at("bufferViews", view);
            const ViewBytes bytes = bufferView(view, v.where);
            const uint64_t stride = bytes.stride.value_or(elementSize);
            if (stride < elementSize || stride > 255)
                fail(viewWhere + ".byteStride: " + std::to_string(stride) + " does not fit " + v.where + "'s " +
                     std::to_string(elementSize) + "-byte elements");
            const uint64_t offset = uintField(a, "byteOffset", v.where, 0);
            const uint64_t viewLength = bytes.length;
            // Bounding count and offset by the view length first keeps the product below 2^64.
            if (count > 0 && (offset > viewLength || count > viewLength || offset + (count - 1) * stride + elementSize > viewLength))
                fail(v.where + ": " + std::to_string(count) + " elements from " + bytes.describe(offset) +
                     " run past the end of " + viewWhere + " (" + std::to_string(viewLength) + " bytes; truncated)");
            v.count = size_t(count);
            v.stride = size_t(stride);
            v.data = count > 0 ? bytes.data + offset : nullptr;  // an empty accessor's offset is unchecked
        }
        if (const json* sparse = member(a, "sparse")) applySparse(*sparse, v, elementSize);
        return v;
    }

    // A sparse accessor: its base (or zeros) copied, then the listed elements replaced.
    // The copy is no larger than the base view or the 2^24 elements of an accessor
    // without one; indices must increase strictly and stay below the accessor's count.
    void applySparse(const json& sparse, AccessorView& v, size_t elementSize) {
        const std::string sw = v.where + ".sparse";
        if (!sparse.is_object()) fail(sw + ": object expected");
        const uint64_t n = uintField(sparse, "count", sw);
        if (n == 0) fail(sw + ".count: at least 1 expected");
        if (n > v.count)
            fail(sw + ".count: " + std::to_string(n) + " substitutions for " + std::to_string(v.count) + " elements");
        const json* indices = member(sparse, "indices");
        const json* values = member(sparse, "values");
        if (!indices || !indices->is_object()) fail(sw + ".indices: object expected");
        if (!values || !values->is_object()) fail(sw + ".values: object expected");
        const uint64_t indexType = uintField(*indices, "componentType", sw + ".indices");
        const size_t indexSize = indexType == 5121 ? 1 : indexType == 5123 ? 2 : indexType == 5125 ? 4 : 0;
        if (!indexSize)
            fail(sw + ".indices.componentType: " + std::to_string(indexType) +
                 " is not 5121, 5123 or 5125 (UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT)");
        const uint8_t* index = sparseData(*indices, sw + ".indices", n, indexSize);
        const uint8_t* value = sparseData(*values, sw + ".values", n, elementSize);

        auto copy = std::make_shared<std::vector<uint8_t>>(v.count * elementSize, uint8_t(0));
        for (size_t k = 0; v.data && k < v.count; ++k)
            std::memcpy(copy->data() + k * elementSize, v.data + k * v.stride, elementSize);
        uint32_t previous = 0;
        for (size_t k = 0; k < n; ++k) {
            const uint32_t e = readUint(index + k * indexSize, indexSize);
            if (e >= v.count)
                fail(sw + ".indices: index " + std::to_string(e) + " at element " + std::to_string(k) +
                     " is out of range (" + v.where + " has " + std::to_string(v.count) + " elements)");
            if (k > 0 && e <= previous)
                fail(sw + ".indices: index " + std::to_string(e) + " at element " + std::to_string(k) +
                     " does not follow " + std::to_string(previous) + " (sparse indices must increase strictly)");
            std::memcpy(copy->data() + size_t(e) * elementSize, value + k * elementSize, elementSize);
            previous = e;
        }
        v.owned = copy;
        v.data = copy->data();
        v.stride = elementSize;
    }

    // `n` tightly packed elements of `size` bytes of a sparse accessor's indices or values.
    const uint8_t* sparseData(const json& part, const std::string& where, uint64_t n, size_t size) {
        const uint64_t view = uintField(part, "bufferView", where);
        const ViewBytes bytes = bufferView(view, where);
        if (bytes.stride && *bytes.stride != size)
            fail(at("bufferViews", view) + ".byteStride: " + std::to_string(*bytes.stride) + ", but " + where +
                 " are tightly packed " + std::to_string(size) + "-byte elements");
        const uint64_t offset = uintField(part, "byteOffset", where, 0);
        // n is at most the accessor's count (2^24, or the base view's length) and size 16.
        if (offset > bytes.length || n * size > bytes.length - offset)
            fail(where + ": " + std::to_string(n) + " elements of " + std::to_string(size) + " bytes from " +
                 bytes.describe(offset) + " run past the end of " + at("bufferViews", view) + " (" +
                 std::to_string(bytes.length) + " bytes; truncated)");
        return bytes.data + offset;
    }

    // Nodes, their transforms and the forest they form. Checked here once so that every
    // traversal after is finite.
    void readNodes() {
        const json& list = array("nodes");
        nodes.resize(list.size());
        for (size_t n = 0; n < list.size(); ++n) {
            const std::string where = at("nodes", n);
            if (!list[n].is_object()) fail(where + ": object expected");
            const json& node = list[n];
            GltfNode& out = nodes[n];
            if (const json* name = member(node, "name")) {
                if (!name->is_string()) fail(where + ".name: string expected");
                out.name = name->get<std::string>();
            }
            if (const json* ext = member(node, "extensions"); ext && ext->is_object()) {
                if (ext->contains("EXT_mesh_gpu_instancing")) fail(where + ": EXT_mesh_gpu_instancing is not supported");
                if (const json* lp = member(*ext, "KHR_lights_punctual")) {
                    if (!lp->is_object()) fail(where + ".extensions.KHR_lights_punctual: object expected");
                    out.light = uintField(*lp, "light", where + ".extensions.KHR_lights_punctual");
                }
            }
            out.local = localTransform(node, where);
            if (member(node, "mesh")) {
                const uint64_t m = uintField(node, "mesh", where);
                if (m >= meshes.size())
                    fail(where + ".mesh: " + at("meshes", m) + " does not exist (" + std::to_string(meshes.size()) + " defined)");
                out.mesh = size_t(m);
            }
            const json* children = member(node, "children");
            if (!children) continue;
            if (!children->is_array()) fail(where + ".children: array expected");
            for (const json& c : *children) {
                if (!c.is_number_unsigned() || c.get<uint64_t>() >= list.size())
                    fail(where + ".children: " + c.dump() + " is not a node index");
                out.children.push_back(c.get<size_t>());
            }
        }
        for (size_t n = 0; n < nodes.size(); ++n)
            for (size_t c : nodes[n].children) {
                if (nodes[c].parent == long(n))
                    fail(at("nodes", n) + ".children: " + at("nodes", c) + " is listed twice (a node is placed once)");
                if (nodes[c].parent >= 0)
                    fail(at("nodes", c) + " has more than one parent (nodes must form trees)");
                nodes[c].parent = long(n);
            }
        // With at most one parent each, a cycle is a chain of parents that comes back.
        std::vector<uint8_t> state(nodes.size(), 0);  // 0 unseen, 1 on the current chain, 2 done
        for (size_t n = 0; n < nodes.size(); ++n) {
            std::vector<size_t> chain;
            long k = long(n);
            while (k >= 0 && state[size_t(k)] == 0) {
                state[size_t(k)] = 1;
                chain.push_back(size_t(k));
                k = nodes[size_t(k)].parent;
            }
            if (k >= 0 && state[size_t(k)] == 1)
                fail(at("nodes", size_t(k)) + " is its own ancestor (the children lists form a cycle)");
            for (size_t c : chain) state[c] = 2;
        }
    }

    std::vector<size_t> sceneRoots(std::optional<size_t> sceneIndex) const {
        std::vector<size_t> roots;
        const json* scenesField = member(doc, "scenes");
        const size_t sceneCount = scenesField && scenesField->is_array() ? scenesField->size() : 0;
        if (scenesField && !scenesField->is_array()) fail("scenes: array expected");
        if (sceneCount == 0) {
            if (sceneIndex) fail("--scene " + std::to_string(*sceneIndex) + ": the file defines no scenes");
            for (size_t n = 0; n < nodes.size(); ++n)
                if (nodes[n].parent < 0) roots.push_back(n);
            return roots;
        }
        const uint64_t s = sceneIndex ? *sceneIndex : uintField(doc, "scene", "glTF", 0);
        if (s >= sceneCount)
            fail((sceneIndex ? "--scene " : "scene: ") + std::to_string(s) + ": " + at("scenes", s) + " does not exist (" +
                 std::to_string(sceneCount) + " defined)");
        const json& scene = (*scenesField)[s];
        const std::string where = at("scenes", s);
        if (!scene.is_object()) fail(where + ": object expected");
        const json* list = member(scene, "nodes");
        if (!list) return roots;
        if (!list->is_array()) fail(where + ".nodes: array expected");
        std::vector<bool> listed(nodes.size(), false);
        for (const json& n : *list) {
            if (!n.is_number_unsigned() || n.get<uint64_t>() >= nodes.size())
                fail(where + ".nodes: " + n.dump() + " is not a node index");
            if (nodes[n.get<size_t>()].parent >= 0)
                fail(where + ".nodes: " + at("nodes", n.get<size_t>()) + " is not a root node");
            // Listed twice, its whole tree would be placed twice: every model doubled.
            if (listed[n.get<size_t>()])
                fail(where + ".nodes: " + at("nodes", n.get<size_t>()) + " is listed twice (a node is placed once)");
            listed[n.get<size_t>()] = true;
            roots.push_back(n.get<size_t>());
        }
        return roots;
    }

    const json& primitives(size_t m) const {
        const json& jm = array("meshes")[m];
        const json* prims = jm.is_object() ? member(jm, "primitives") : nullptr;
        if (!prims || !prims->is_array()) fail(at("meshes", m) + ".primitives: array expected");
        for (size_t p = 0; p < prims->size(); ++p)
            if (!(*prims)[p].is_object()) fail(at(at("meshes", m) + ".primitives", p) + ": object expected");
        return *prims;
    }

    std::vector<PrimitiveGroup> groups(size_t m) const {
        const json& prims = primitives(m);
        std::vector<PrimitiveGroup> out(prims.size());
        for (size_t p = 0; p < prims.size(); ++p) {
            out[p].name = "mesh" + std::to_string(m) + "/primitive" + std::to_string(p);
            readMaterial(prims[p], at(at("meshes", m) + ".primitives", p), out[p]);
        }
        return out;
    }

    const std::vector<GltfPrimitive>& mesh(size_t m, const std::string& referrer) {
        if (m >= meshes.size())
            fail(referrer + ": " + at("meshes", m) + " does not exist (" + std::to_string(meshes.size()) + " defined)");
        if (meshes[m]) return *meshes[m];
        const json& prims = primitives(m);
        std::vector<PrimitiveGroup> flags = groups(m);
        std::vector<GltfPrimitive> out(prims.size());
        for (size_t p = 0; p < prims.size(); ++p) {
            out[p].group = flags[p];
            decodePrimitive(prims[p], at(at("meshes", m) + ".primitives", p), out[p]);
        }
        meshes[m] = std::move(out);
        return *meshes[m];
    }

    void readMaterial(const json& prim, const std::string& primWhere, PrimitiveGroup& g) const {
        if (!member(prim, "material")) return;
        const uint64_t mi = uintField(prim, "material", primWhere);
        const json& mat = element("materials", mi, primWhere);
        const std::string matWhere = at("materials", mi);
        const json alphaMode = mat.value("alphaMode", json("OPAQUE"));
        if (alphaMode == "MASK" || alphaMode == "BLEND") g.alphaTested = true;
        else if (alphaMode != "OPAQUE") fail(matWhere + ".alphaMode: OPAQUE, MASK or BLEND expected");
        const json doubleSided = mat.value("doubleSided", json(false));
        if (!doubleSided.is_boolean()) fail(matWhere + ".doubleSided: true or false expected");
        g.doubleSided = doubleSided.get<bool>();
    }

    void decodePrimitive(const json& prim, const std::string& where, GltfPrimitive& out) {
        const uint64_t mode = uintField(prim, "mode", where, 4);
        if (mode > 6) fail(where + ".mode: unknown value " + std::to_string(mode));
        if (mode < 4) {  // points and lines cast no shadow
            warnings.push_back({path, 0, where + ": mode " + std::to_string(mode) + " (points or lines) has no triangles; skipped"});
            return;
        }
        const json* attributes = member(prim, "attributes");
        if (!attributes || !attributes->is_object() || !member(*attributes, "POSITION"))
            fail(where + ".attributes.POSITION is missing");
        if (const json* ext = member(prim, "extensions"); ext && ext->is_object())
            if (const json* draco = member(*ext, "KHR_draco_mesh_compression"))
                return decodeDraco(prim, *draco, *attributes, where, mode, out);
        const AccessorView pos = accessor(uintField(*attributes, "POSITION", where + ".attributes"), where);
        if (pos.type != "VEC3") fail(pos.where + ": POSITION must be VEC3, not " + pos.type);
        // FLOAT, or the integer types of KHR_mesh_quantization (the dequantizing scale and
        // offset, if any, are in the node transform, which the callers apply).
        if (pos.componentType == 5125)
            fail(pos.where + ": POSITION componentType 5125 (UNSIGNED_INT) is not allowed (FLOAT, or BYTE, UNSIGNED_BYTE, " +
                 "SHORT, UNSIGNED_SHORT of KHR_mesh_quantization)");
        // Without the extension glTF positions are FLOAT: integer ones mean a file that is
        // not what it says, not quantized positions to guess a scale for.
        if (pos.componentType != 5126 && !declares("KHR_mesh_quantization"))
            fail(pos.where + ": POSITION componentType " + std::to_string(pos.componentType) + " (" +
                 integerComponentName(pos.componentType) +
                 ") needs KHR_mesh_quantization in extensionsUsed (without it, positions are FLOAT)");
        const size_t size = componentSize(pos.componentType);
        spend(pos.count, pos.where);
        out.positions.resize(pos.count, glm::dvec3(0.0));
        for (size_t k = 0; pos.data && k < pos.count; ++k) {
            const uint8_t* e = pos.data + k * pos.stride;
            const glm::dvec3 p(component(e, pos.componentType, pos.normalized),
                               component(e + size, pos.componentType, pos.normalized),
                               component(e + 2 * size, pos.componentType, pos.normalized));
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
                fail(pos.where + ": POSITION " + std::to_string(k) + " is not finite (byte offset " +
                     std::to_string(k * pos.stride) + " in the accessor)");
            out.positions[k] = p;
        }

        std::vector<uint32_t> indices;
        if (member(prim, "indices")) {
            const AccessorView ix = accessor(uintField(prim, "indices", where), where);
            const size_t size = ix.componentType == 5121 ? 1 : ix.componentType == 5123 ? 2 : ix.componentType == 5125 ? 4 : 0;
            if (ix.type != "SCALAR" || !size)
                fail(ix.where + ": indices must be SCALAR UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT");
            spend(ix.count, ix.where);
            indices.resize(ix.count, 0);
            for (size_t k = 0; ix.data && k < ix.count; ++k) {
                indices[k] = readUint(ix.data + k * ix.stride, size);
                if (indices[k] >= pos.count)
                    fail(ix.where + ": index " + std::to_string(indices[k]) + " at element " + std::to_string(k) +
                         " is out of range (" + pos.where + " has " + std::to_string(pos.count) + " positions)");
            }
        } else {
            if (pos.count > UINT32_MAX) fail(pos.where + ": too many vertices for 32-bit indices");
            spend(pos.count, pos.where);
            indices.resize(pos.count);
            for (size_t k = 0; k < indices.size(); ++k) indices[k] = uint32_t(k);
        }

        const size_t n = indices.size();
        if (mode == 4 && n % 3 != 0)
            fail(where + ": " + std::to_string(n) + " vertices do not make whole triangles (truncated?)");
        if (mode != 4 && n > 0 && n < 3) fail(where + ": a strip or fan needs at least 3 vertices");
        out.triangles.reserve(mode == 4 ? n / 3 : n);
        const auto& v = indices;
        if (mode == 4)
            for (size_t k = 0; k + 2 < n; k += 3) out.triangles.push_back({v[k], v[k + 1], v[k + 2]});
        if (mode == 5)  // glTF spec: triangle k is {v[k], v[k + 1 + k%2], v[k + 2 - k%2]}
            for (size_t k = 0; k + 2 < n; ++k) out.triangles.push_back({v[k], v[k + 1 + k % 2], v[k + 2 - k % 2]});
        if (mode == 6)  // glTF spec: triangle k is {v[k + 1], v[k + 2], v[0]}
            for (size_t k = 0; k + 2 < n; ++k) out.triangles.push_back({v[k + 1], v[k + 2], v[0]});
    }

    // KHR_draco_mesh_compression: the primitive's positions and faces decoded by libdraco
    // from the extension's bufferView; the primitive's accessors only state what the
    // decoded data must be (their bufferViews, if any, hold an uncompressed fallback that
    // is not read).
    void decodeDraco(const json& prim, const json& ext, const json& attributes, const std::string& where, uint64_t mode,
                     GltfPrimitive& out) {
        const std::string dw = where + ".extensions.KHR_draco_mesh_compression";
        if (!ext.is_object()) fail(dw + ": object expected");
        // Draco decodes to triangles; a strip's index order is not kept in that form.
        if (mode != 4) fail(where + ".mode: " + std::to_string(mode) + " with KHR_draco_mesh_compression is not supported (4 expected)");
        const json* ids = member(ext, "attributes");
        if (!ids || !ids->is_object() || !member(*ids, "POSITION")) fail(dw + ".attributes.POSITION is missing");
        const uint64_t id = uintField(*ids, "POSITION", dw + ".attributes");
        const uint64_t view = uintField(ext, "bufferView", dw);
        const ViewBytes bytes = bufferView(view, dw);

        // What the accessors say the decoded data is.
        const uint64_t posIndex = uintField(attributes, "POSITION", where + ".attributes");
        const std::string posWhere = at("accessors", posIndex);
        const json& posAccessor = element("accessors", posIndex, where);
        if (posAccessor.value("type", json()) != "VEC3") fail(posWhere + ": POSITION must be VEC3");
        const uint64_t posCount = uintField(posAccessor, "count", posWhere);
        std::optional<uint64_t> indexCount;
        std::string indexWhere;
        if (member(prim, "indices")) {
            const uint64_t ix = uintField(prim, "indices", where);
            indexWhere = at("accessors", ix);
            indexCount = uintField(element("accessors", ix, where), "count", indexWhere);
        }

        // Bounded before the decoder's output is copied (spend() below checks the same).
        const uint64_t left = 64 * (fileBytes + bufferBytes) + (uint64_t(1) << 24) - decodedElements;
        Expected<gltf_codecs::DracoMesh> mesh = gltf_codecs::decodeDraco(bytes.data, size_t(bytes.length), id, left);
        if (!mesh) fail(dw + ": the Draco data of " + at("bufferViews", view) + " " + mesh.error().message);
        const uint64_t points = mesh->positions.size(), faces = mesh->triangles.size();
        if (points != posCount)
            fail(posWhere + ".count: " + std::to_string(posCount) + ", but the Draco data of " + where + " has " +
                 std::to_string(points) + " points");
        if (indexCount && *indexCount != 3 * faces)
            fail(indexWhere + ".count: " + std::to_string(*indexCount) + ", but the Draco data of " + where + " has " +
                 std::to_string(faces) + " triangles");
        spend(points + 3 * faces, where);
        out.positions = std::move(mesh->positions);
        out.triangles = std::move(mesh->triangles);
    }

};

namespace {

// Runs `f` and turns a failure into an Error naming the document.
template <class F>
auto guarded(const std::string& path, F&& f) -> Expected<decltype(f())> {
    try {
        return f();
    } catch (const GltfFailure& e) {
        return makeError(e.kind, path, e.line, e.message);
    } catch (const json::exception& e) {
        // Type mismatches the explicit checks did not anticipate.
        return makeError(ErrorKind::BadInput, path, 0, std::string("unexpected JSON content: ") + e.what());
    }
}

}  // namespace

GltfDocument::GltfDocument(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
GltfDocument::GltfDocument(GltfDocument&&) noexcept = default;
GltfDocument& GltfDocument::operator=(GltfDocument&&) noexcept = default;
GltfDocument::~GltfDocument() = default;

Expected<GltfDocument> GltfDocument::open(const std::string& path) {
    auto impl = std::make_unique<Impl>();
    impl->path = path;
    impl->sourceFiles.push_back(path);
    Expected<bool> opened = guarded(path, [&] {
        impl->open();
        return true;
    });
    if (!opened) return opened.error();
    return GltfDocument(std::move(impl));
}

const std::string& GltfDocument::path() const { return impl_->path; }
const json& GltfDocument::json() const { return impl_->doc; }
bool GltfDocument::isGlb() const { return impl_->isGlb; }
const std::vector<GltfNode>& GltfDocument::nodes() const { return impl_->nodes; }
size_t GltfDocument::meshCount() const { return impl_->meshes.size(); }
std::vector<std::string> GltfDocument::sourceFiles() const { return impl_->sourceFiles; }
std::vector<Diagnostic> GltfDocument::warnings() const { return impl_->warnings; }

Expected<std::vector<size_t>> GltfDocument::sceneRoots(std::optional<size_t> scene) const {
    return guarded(impl_->path, [&] { return impl_->sceneRoots(scene); });
}

Expected<std::vector<PrimitiveGroup>> GltfDocument::groups(size_t m) const {
    return guarded(impl_->path, [&] {
        if (m >= impl_->meshes.size()) fail(gltfPath("meshes", m) + " does not exist");
        return impl_->groups(m);
    });
}

Expected<const std::vector<GltfPrimitive>*> GltfDocument::mesh(size_t m, const std::string& referrer) {
    return guarded(impl_->path, [&] { return &impl_->mesh(m, referrer); });
}

}  // namespace shadowcull
