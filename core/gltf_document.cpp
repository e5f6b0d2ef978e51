// glTF 2.0 documents: container (.gltf/.glb), buffers, accessors, node forest and mesh
// decoding (core/gltf_document.h). Only what shadow culling needs is decoded; every range
// is checked against the real data so that a truncated or inconsistent file is an error
// naming the file and the JSON path, never a wrong mesh.

#include "core/gltf_document.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <nlohmann/json.hpp>

#include "core/file_read.h"
#include "core/format.h"
#include "core/limits.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace shadowcull {
namespace {

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

// A regular file only (core/file_read.h: a FIFO or directory is refused, never waited on).
void readFile(const fs::path& path, const std::string& what, std::vector<uint8_t>& out) {
    Expected<std::string> text = readRegularFile(path.string(), what);
    if (!text) fail(what + " '" + path.string() + "': " + text.error().message, text.error().kind);
    out.assign(text->begin(), text->end());
}

// Little-endian reads that do not depend on host byte order or alignment.
uint32_t readUint(const uint8_t* p, size_t bytes) {
    uint32_t v = 0;
    for (size_t k = 0; k < bytes; ++k) v |= uint32_t(p[k]) << (8 * k);
    return v;
}

float readFloat(const uint8_t* p) {
    uint32_t u = readUint(p, 4);
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}

bool decodeBase64(std::string_view s, std::vector<uint8_t>& out) {
    uint32_t acc = 0;
    int bits = 0;
    size_t k = 0;
    for (; k < s.size() && s[k] != '='; ++k) {
        const char c = s[k];
        int v = c >= 'A' && c <= 'Z' ? c - 'A' : c >= 'a' && c <= 'z' ? c - 'a' + 26 : c >= '0' && c <= '9' ? c - '0' + 52
              : c == '+' ? 62 : c == '/' ? 63 : -1;
        if (v < 0) return false;
        acc = ((acc << 6) | uint32_t(v)) & 0xffffff;
        if ((bits += 6) >= 8) out.push_back(uint8_t(acc >> (bits -= 8)));
    }
    return s.find_first_not_of('=', k) == std::string_view::npos;
}

std::string percentDecode(const std::string& s) {
    std::string out;
    for (size_t k = 0; k < s.size(); ++k) {
        if (s[k] == '%' && k + 2 < s.size() && std::isxdigit((unsigned char)s[k + 1]) && std::isxdigit((unsigned char)s[k + 2])) {
            out += char(std::stoi(s.substr(k + 1, 2), nullptr, 16));
            k += 2;
        } else {
            out += s[k];
        }
    }
    return out;
}

std::string at(const std::string& array, size_t i) { return gltfPath(array, i); }

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

// A column-major glTF matrix or the product T * R * S of the TRS properties.
glm::dmat4 localTransform(const json& node, const std::string& where) {
    glm::dmat4 m(1.0);
    if (member(node, "matrix")) {
        std::vector<double> v = numbers(node, "matrix", where, 16);
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r) m[c][r] = v[size_t(c * 4 + r)];
        return m;
    }
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
// elements are all zero by the glTF spec.
struct AccessorView {
    std::string where;
    uint64_t componentType = 0;
    std::string type;
    size_t count = 0;
    size_t stride = 0;
    const uint8_t* data = nullptr;
};


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

    void open() {
        readContainer();
        if (!doc.is_object()) fail("the JSON top level must be an object");
        if (const json* asset = member(doc, "asset"); asset && asset->is_object()) {
            const json* version = member(*asset, "version");
            if (version && version->is_string() && version->get<std::string>().rfind("2.", 0) != 0)
                fail("asset.version: glTF " + version->get<std::string>() + " is not supported (2.x expected)");
        }
        if (const json* required = member(doc, "extensionsRequired"); required && required->is_array()) {
            // Compressed geometry would otherwise be read as the (absent) plain accessors.
            for (const json& e : *required)
                if (e == "KHR_draco_mesh_compression" || e == "EXT_meshopt_compression")
                    fail("extensionsRequired: " + e.get<std::string>() + " is not supported");
        }
        buffers.resize(array("buffers").size());  // before any buffer() hands out references
        meshes.resize(array("meshes").size());
        readNodes();
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
                const fs::path file = fs::path(path).parent_path() / percentDecode(uri);
                readFile(file, where + ": buffer file", data);
                sourceFiles.push_back(file.string());
            }
        }
        if (data.size() < byteLength)
            fail(where + ": byteLength is " + std::to_string(byteLength) + " but only " + std::to_string(data.size()) +
                 " bytes are present (truncated)");
        data.resize(size_t(byteLength));  // GLB padding is not part of the buffer
        buffers[i] = std::move(data);
        return *buffers[i];
    }

    AccessorView accessor(uint64_t i, const std::string& referrer) {
        AccessorView v;
        v.where = at("accessors", i);
        const json& a = element("accessors", i, referrer);
        if (member(a, "sparse")) fail(v.where + ": sparse accessors are not supported");
        v.componentType = uintField(a, "componentType", v.where);
        const size_t componentSize = v.componentType == 5120 || v.componentType == 5121 ? 1
                                   : v.componentType == 5122 || v.componentType == 5123 ? 2
                                   : v.componentType == 5125 || v.componentType == 5126 ? 4 : 0;
        if (!componentSize) fail(v.where + ".componentType: unknown value " + std::to_string(v.componentType));
        const json* type = member(a, "type");
        if (!type || !type->is_string()) fail(v.where + ".type: string expected");
        v.type = type->get<std::string>();
        const uint64_t count = uintField(a, "count", v.where);
        const size_t components = v.type == "SCALAR" ? 1 : v.type == "VEC2" ? 2 : v.type == "VEC3" ? 3 : v.type == "VEC4" ? 4 : 0;
        if (!components) fail(v.where + ".type: '" + v.type + "' is not SCALAR or VECn");
        const size_t elementSize = componentSize * components;
        const json* viewIndex = member(a, "bufferView");
        if (!viewIndex) {
            // All-zero data: legitimate only in small amounts, so a huge count means corruption
            // (and must not become a huge allocation).
            if (count > (uint64_t(1) << 24)) fail(v.where + ": count " + std::to_string(count) + " without bufferView");
            v.count = size_t(count);
            return v;
        }
        const uint64_t view = uintField(a, "bufferView", v.where);
        const std::string viewWhere = at("bufferViews", view);
        const json& bv = element("bufferViews", view, v.where);
        const uint64_t viewOffset = uintField(bv, "byteOffset", viewWhere, 0);
        const uint64_t viewLength = uintField(bv, "byteLength", viewWhere);
        const uint64_t stride = uintField(bv, "byteStride", viewWhere, elementSize);
        const std::vector<uint8_t>& buf = buffer(uintField(bv, "buffer", viewWhere), viewWhere);
        if (viewOffset > buf.size() || viewLength > buf.size() - viewOffset)
            fail(viewWhere + ": bytes " + std::to_string(viewOffset) + ".." + std::to_string(viewOffset + viewLength) +
                 " lie outside its buffer of " + std::to_string(buf.size()) + " bytes (truncated)");
        if (stride < elementSize || stride > 255)
            fail(viewWhere + ".byteStride: " + std::to_string(stride) + " does not fit " + v.where + "'s " +
                 std::to_string(elementSize) + "-byte elements");
        const uint64_t offset = uintField(a, "byteOffset", v.where, 0);
        // Bounding count and offset by the view length first keeps the product below 2^64.
        if (count > 0 && (offset > viewLength || count > viewLength || offset + (count - 1) * stride + elementSize > viewLength))
            fail(v.where + ": " + std::to_string(count) + " elements from byte offset " +
                 std::to_string(viewOffset + offset) + " of " + at("buffers", uintField(bv, "buffer", viewWhere)) +
                 " run past the end of " + viewWhere + " (" + std::to_string(viewLength) + " bytes; truncated)");
        v.count = size_t(count);
        v.stride = size_t(stride);
        v.data = buf.data() + viewOffset + offset;
        return v;
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
        for (const json& n : *list) {
            if (!n.is_number_unsigned() || n.get<uint64_t>() >= nodes.size())
                fail(where + ".nodes: " + n.dump() + " is not a node index");
            if (nodes[n.get<size_t>()].parent >= 0)
                fail(where + ".nodes: " + at("nodes", n.get<size_t>()) + " is not a root node");
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
        const AccessorView pos = accessor(uintField(*attributes, "POSITION", where + ".attributes"), where);
        if (pos.type != "VEC3") fail(pos.where + ": POSITION must be VEC3, not " + pos.type);
        if (pos.componentType != 5126)
            fail(pos.where + ": POSITION componentType " + std::to_string(pos.componentType) +
                 " is not supported (5126 FLOAT expected; quantized positions of KHR_mesh_quantization are not read)");
        out.positions.resize(pos.count, glm::dvec3(0.0));
        for (size_t k = 0; pos.data && k < pos.count; ++k) {
            const uint8_t* e = pos.data + k * pos.stride;
            const glm::dvec3 p(readFloat(e), readFloat(e + 4), readFloat(e + 8));
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
            indices.resize(ix.count, 0);
            for (size_t k = 0; ix.data && k < ix.count; ++k) {
                indices[k] = readUint(ix.data + k * ix.stride, size);
                if (indices[k] >= pos.count)
                    fail(ix.where + ": index " + std::to_string(indices[k]) + " at element " + std::to_string(k) +
                         " is out of range (" + pos.where + " has " + std::to_string(pos.count) + " positions)");
            }
        } else {
            if (pos.count > UINT32_MAX) fail(pos.where + ": too many vertices for 32-bit indices");
            indices.resize(pos.count);
            for (size_t k = 0; k < indices.size(); ++k) indices[k] = uint32_t(k);
        }

        const size_t n = indices.size();
        if (mode == 4 && n % 3 != 0)
            fail(where + ": " + std::to_string(n) + " vertices do not make whole triangles (truncated?)");
        if (mode != 4 && n > 0 && n < 3) fail(where + ": a strip or fan needs at least 3 vertices");
        const auto& v = indices;
        if (mode == 4)
            for (size_t k = 0; k + 2 < n; k += 3) out.triangles.push_back({v[k], v[k + 1], v[k + 2]});
        if (mode == 5)  // glTF spec: triangle k is {v[k], v[k + 1 + k%2], v[k + 2 - k%2]}
            for (size_t k = 0; k + 2 < n; ++k) out.triangles.push_back({v[k], v[k + 1 + k % 2], v[k + 2 - k % 2]});
        if (mode == 6)  // glTF spec: triangle k is {v[k + 1], v[k + 2], v[0]}
            for (size_t k = 0; k + 2 < n; ++k) out.triangles.push_back({v[k + 1], v[k + 2], v[0]});
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
