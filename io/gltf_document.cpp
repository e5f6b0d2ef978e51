// glTF 2.0 documents (io/gltf_document.h): the public class, the container (.gltf/.glb),
// buffers, buffer views and accessors. Nodes, scenes and mesh decoding are in
// io/gltf_meshes.cpp; what both share is in io/gltf_document_impl.h. Only what shadow
// culling needs is decoded; every range is checked against the real data so that a
// truncated or inconsistent file is an error naming the file and the JSON path, never a
// wrong mesh.
//
// Read as real pipelines write it: KHR_mesh_quantization (integer positions, normalized
// or not), sparse accessors, EXT_meshopt_compression buffer views (decoded by Debian's
// libmeshoptimizer, once per view) and KHR_draco_mesh_compression primitives (decoded by
// Debian's libdraco). The compressed formats are decoded by their reference libraries;
// everything around them (ranges, counts, strides, modes) is checked here first, since
// both libraries assert or trust their arguments.

#include "io/gltf_document_impl.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>

#include "io/file_read.h"
#include "io/gltf_codecs.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace shadowcull {
using namespace gltf_detail;
namespace {

using gltf_codecs::componentSize;
using gltf_codecs::decodeBase64;
using gltf_codecs::percentDecode;
using gltf_codecs::readUint;

// A regular file only (io/file_read.h: a FIFO or directory is refused, never waited on).
void readFile(const fs::path& path, const std::string& what, std::vector<uint8_t>& out) {
    Expected<std::string> text = readRegularFile(path.string(), what);
    if (!text) fail(what + " '" + path.string() + "': " + text.error().message, text.error().kind);
    out.assign(text->begin(), text->end());
}

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

std::string gltfPath(const std::string& array, size_t index) { return array + "[" + std::to_string(index) + "]"; }

void GltfDocument::Impl::open() {
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
void GltfDocument::Impl::checkRequiredExtensions() const {
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
bool GltfDocument::Impl::declares(const char* name) const {
    for (const char* list : {"extensionsUsed", "extensionsRequired"})
        if (const json* l = member(doc, list); l && l->is_array() && std::find(l->begin(), l->end(), name) != l->end())
            return true;
    return false;
}

const json& GltfDocument::Impl::array(const char* name) const {
    static const json empty = json::array();
    const json* a = member(doc, name);
    if (!a) return empty;
    if (!a->is_array()) fail(std::string(name) + ": array expected");
    return *a;
}

// Element `i` of top-level array `name`, referenced from `referrer`.
const json& GltfDocument::Impl::element(const char* name, uint64_t i, const std::string& referrer) const {
    const json& a = array(name);
    if (i >= a.size())
        fail(referrer + ": " + at(name, i) + " does not exist (" + std::to_string(a.size()) + " defined)");
    if (!a[i].is_object()) fail(at(name, i) + ": object expected");
    return a[i];
}

void GltfDocument::Impl::readContainer() {
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

void GltfDocument::Impl::readGlb(const std::vector<uint8_t>& bytes, std::string& text) {
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

const std::vector<uint8_t>& GltfDocument::Impl::buffer(uint64_t i, const std::string& referrer) {
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
ViewBytes GltfDocument::Impl::bufferView(uint64_t view, const std::string& referrer) {
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
const std::vector<uint8_t>& GltfDocument::Impl::meshoptView(uint64_t view, const json& bv, const json& ext,
                                                            const std::string& where, uint64_t viewLength) {
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

AccessorView GltfDocument::Impl::accessor(uint64_t i, const std::string& referrer) {
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
void GltfDocument::Impl::applySparse(const json& sparse, AccessorView& v, size_t elementSize) {
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
const uint8_t* GltfDocument::Impl::sparseData(const json& part, const std::string& where, uint64_t n, size_t size) {
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
