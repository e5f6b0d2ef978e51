// glTF 2.0 documents, the part that reads what the file draws (io/gltf_document.h): the
// node forest and node transforms, scenes, meshes, materials and primitives decoded to
// triangles, including KHR_mesh_quantization positions and KHR_draco_mesh_compression
// primitives (decoded by Debian's libdraco; counts and modes are checked here first, since
// the library trusts its arguments). Buffers, views and accessors are io/gltf_document.cpp's.

#include "io/gltf_document_impl.h"

#include <cmath>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>

#include "io/gltf_codecs.h"
#include "util/format.h"

using nlohmann::json;

namespace shadowcull {
using namespace gltf_detail;
namespace {

using gltf_codecs::component;
using gltf_codecs::componentSize;
using gltf_codecs::readUint;

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

// Triangles from the vertex indices of a TRIANGLES (4), TRIANGLE_STRIP (5) or TRIANGLE_FAN
// (6) primitive, counter-clockwise from the front as glTF defines it.
void assembleTriangles(const std::vector<uint32_t>& v, uint64_t mode, const std::string& where,
                       std::vector<std::array<uint32_t, 3>>& triangles) {
    const size_t n = v.size();
    if (mode == 4 && n % 3 != 0)
        fail(where + ": " + std::to_string(n) + " vertices do not make whole triangles (truncated?)");
    if (mode != 4 && n > 0 && n < 3) fail(where + ": a strip or fan needs at least 3 vertices");
    triangles.reserve(mode == 4 ? n / 3 : n);
    if (mode == 4)
        for (size_t k = 0; k + 2 < n; k += 3) triangles.push_back({v[k], v[k + 1], v[k + 2]});
    if (mode == 5)  // glTF spec: triangle k is {v[k], v[k + 1 + k%2], v[k + 2 - k%2]}
        for (size_t k = 0; k + 2 < n; ++k) triangles.push_back({v[k], v[k + 1 + k % 2], v[k + 2 - k % 2]});
    if (mode == 6)  // glTF spec: triangle k is {v[k + 1], v[k + 2], v[0]}
        for (size_t k = 0; k + 2 < n; ++k) triangles.push_back({v[k + 1], v[k + 2], v[0]});
}

}  // namespace

void GltfDocument::Impl::spend(uint64_t elements, const std::string& where) {
    const uint64_t budget = elementBudget();
    decodedElements += elements;
    if (decodedElements > budget)
        fail(where + ": decoding would give " + std::to_string(decodedElements) + " vertices and indices from " +
             std::to_string(fileBytes + bufferBytes) +
             " bytes of file and buffers, more than 64 per byte (accessors shared by many primitives, or a "
             "corrupt count)");
}

// Nodes, their transforms and the forest they form. Checked here once so that every
// traversal after is finite.
void GltfDocument::Impl::readNodes() {
    const json& list = array("nodes");
    nodes.resize(list.size());
    for (size_t n = 0; n < list.size(); ++n) readNode(list, n);
    linkChildren();
    checkAcyclic();
}

// Node `n` of `list` (the top-level nodes array): name, light, transform, mesh, children.
void GltfDocument::Impl::readNode(const json& list, size_t n) {
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
    if (!children) return;
    if (!children->is_array()) fail(where + ".children: array expected");
    for (const json& c : *children) {
        if (!c.is_number_unsigned() || c.get<uint64_t>() >= list.size())
            fail(where + ".children: " + c.dump() + " is not a node index");
        out.children.push_back(c.get<size_t>());
    }
}

// Each node's parent, from the children lists: a node is listed once, by one parent.
void GltfDocument::Impl::linkChildren() {
    for (size_t n = 0; n < nodes.size(); ++n)
        for (size_t c : nodes[n].children) {
            if (nodes[c].parent == long(n))
                fail(at("nodes", n) + ".children: " + at("nodes", c) + " is listed twice (a node is placed once)");
            if (nodes[c].parent >= 0)
                fail(at("nodes", c) + " has more than one parent (nodes must form trees)");
            nodes[c].parent = long(n);
        }
}

// With at most one parent each, a cycle is a chain of parents that comes back.
void GltfDocument::Impl::checkAcyclic() const {
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

std::vector<size_t> GltfDocument::Impl::sceneRoots(std::optional<size_t> sceneIndex) const {
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

const json& GltfDocument::Impl::primitives(size_t m) const {
    const json& jm = array("meshes")[m];
    const json* prims = jm.is_object() ? member(jm, "primitives") : nullptr;
    if (!prims || !prims->is_array()) fail(at("meshes", m) + ".primitives: array expected");
    for (size_t p = 0; p < prims->size(); ++p)
        if (!(*prims)[p].is_object()) fail(at(at("meshes", m) + ".primitives", p) + ": object expected");
    return *prims;
}

std::vector<PrimitiveGroup> GltfDocument::Impl::groups(size_t m) const {
    const json& prims = primitives(m);
    std::vector<PrimitiveGroup> out(prims.size());
    for (size_t p = 0; p < prims.size(); ++p) {
        out[p].name = "mesh" + std::to_string(m) + "/primitive" + std::to_string(p);
        readMaterial(prims[p], at(at("meshes", m) + ".primitives", p), out[p]);
    }
    return out;
}

const std::vector<GltfPrimitive>& GltfDocument::Impl::mesh(size_t m, const std::string& referrer) {
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

void GltfDocument::Impl::readMaterial(const json& prim, const std::string& primWhere, PrimitiveGroup& g) const {
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

void GltfDocument::Impl::decodePrimitive(const json& prim, const std::string& where, GltfPrimitive& out) {
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
    const AccessorView pos = decodePositions(*attributes, where, out);
    const std::vector<uint32_t> indices = decodeIndices(prim, where, pos);
    assembleTriangles(indices, mode, where, out.triangles);
}

// The primitive's POSITION accessor, read into out.positions.
AccessorView GltfDocument::Impl::decodePositions(const json& attributes, const std::string& where, GltfPrimitive& out) {
    const AccessorView pos = accessor(uintField(attributes, "POSITION", where + ".attributes"), where);
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
    return pos;
}

// The primitive's vertex indices: its indices accessor, or 0, 1, 2, ... over the positions.
std::vector<uint32_t> GltfDocument::Impl::decodeIndices(const json& prim, const std::string& where,
                                                        const AccessorView& pos) {
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
    return indices;
}

// KHR_draco_mesh_compression: the primitive's positions and faces decoded by libdraco
// from the extension's bufferView; the primitive's accessors only state what the
// decoded data must be (their bufferViews, if any, hold an uncompressed fallback that
// is not read).
void GltfDocument::Impl::decodeDraco(const json& prim, const json& ext, const json& attributes,
                                     const std::string& where, uint64_t mode, GltfPrimitive& out) {
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
    const uint64_t left = elementBudget() - decodedElements;
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

}  // namespace shadowcull
