#include "tests/support/gltf_scenes.h"

#include <cmath>
#include <cstring>

#include <glm/geometric.hpp>

namespace shadowcull::testing {

namespace {

using nlohmann::json;

void appendU32(std::string& s, uint32_t v) {
    for (int k = 0; k < 4; ++k) s += char((v >> (8 * k)) & 0xff);
}

std::string base64(const std::string& d) {
    static const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < d.size(); i += 3) {
        uint32_t v = uint32_t(uint8_t(d[i])) << 16;
        if (i + 1 < d.size()) v |= uint32_t(uint8_t(d[i + 1])) << 8;
        if (i + 2 < d.size()) v |= uint8_t(d[i + 2]);
        out += alphabet[(v >> 18) & 63];
        out += alphabet[(v >> 12) & 63];
        out += i + 1 < d.size() ? alphabet[(v >> 6) & 63] : '=';
        out += i + 2 < d.size() ? alphabet[v & 63] : '=';
    }
    return out;
}

// Appends triangle (a, b, c) wound so that its normal points along `outward`.
void addOriented(std::vector<uint32_t>& idx, const std::vector<glm::vec3>& p, uint32_t a, uint32_t b, uint32_t c,
                 const glm::vec3& outward) {
    const glm::vec3 n = glm::cross(p[b] - p[a], p[c] - p[a]);
    if (glm::dot(n, outward) >= 0) idx.insert(idx.end(), {a, b, c});
    else idx.insert(idx.end(), {a, c, b});
}

}  // namespace

GltfSceneBuilder::GltfSceneBuilder() {
    doc_ = {{"asset", {{"version", "2.0"}, {"generator", "shadowcull tests/support/gltf_scenes"}}},
            {"scene", 0},
            {"scenes", json::array({{{"nodes", json::array()}}})},
            {"nodes", json::array()},
            {"meshes", json::array()},
            {"materials", json::array()},
            {"accessors", json::array()},
            {"bufferViews", json::array()}};
}

size_t GltfSceneBuilder::material(const std::string& name, bool alphaMask, bool doubleSided) {
    json m = {{"name", name}, {"doubleSided", doubleSided}};
    if (alphaMask) {
        m["alphaMode"] = "MASK";
        // A 2x2 RGBA PNG: two opaque texels, two transparent ones.
        if (!doc_.contains("images")) {
            json image = {{"uri", "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAIAAAACCAYAAABytg0kAAAAEUlEQVR4nGP4DwEMDCACxAIAgJEN837B/94AAAAASUVORK5CYII="}};
            doc_["images"] = json::array({image});
            doc_["textures"] = json::array({json{{"source", 0}}});
        }
        m["pbrMetallicRoughness"] = {{"baseColorTexture", {{"index", 0}}}};
    }
    doc_["materials"].push_back(m);
    return doc_["materials"].size() - 1;
}

size_t GltfSceneBuilder::mesh(const std::string& name, const std::vector<Primitive>& primitives) {
    json prims = json::array();
    for (const Primitive& p : primitives) {
        auto view = [&](const std::string& bytes, int target) {
            while (bin_.size() % 4) bin_ += '\0';
            doc_["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", bytes.size()}, {"target", target}});
            bin_ += bytes;
            return doc_["bufferViews"].size() - 1;
        };
        std::string pos, idx;
        glm::vec3 lo(1e30f), hi(-1e30f);
        for (const glm::vec3& v : p.positions) {
            for (int c = 0; c < 3; ++c) {
                uint32_t u;
                std::memcpy(&u, &v[c], 4);
                appendU32(pos, u);
            }
            lo = glm::min(lo, v);
            hi = glm::max(hi, v);
        }
        for (uint32_t i : p.indices) appendU32(idx, i);
        const size_t pv = view(pos, 34962);
        doc_["accessors"].push_back({{"bufferView", pv}, {"componentType", 5126}, {"count", p.positions.size()}, {"type", "VEC3"},
                                     {"min", {lo.x, lo.y, lo.z}}, {"max", {hi.x, hi.y, hi.z}}});
        const size_t pa = doc_["accessors"].size() - 1;
        const size_t iv = view(idx, 34963);
        doc_["accessors"].push_back({{"bufferView", iv}, {"componentType", 5125}, {"count", p.indices.size()}, {"type", "SCALAR"}});
        json prim = {{"attributes", {{"POSITION", pa}}}, {"indices", doc_["accessors"].size() - 1}};
        if (!p.uvs.empty()) {
            std::string uv;
            for (const glm::vec2& t : p.uvs)
                for (int c = 0; c < 2; ++c) {
                    uint32_t u;
                    std::memcpy(&u, &t[c], 4);
                    appendU32(uv, u);
                }
            const size_t tv = view(uv, 34962);
            doc_["accessors"].push_back({{"bufferView", tv}, {"componentType", 5126}, {"count", p.uvs.size()}, {"type", "VEC2"}});
            prim["attributes"]["TEXCOORD_0"] = doc_["accessors"].size() - 1;
        }
        if (p.material >= 0) prim["material"] = p.material;
        prims.push_back(prim);
    }
    doc_["meshes"].push_back({{"name", name}, {"primitives", prims}});
    return doc_["meshes"].size() - 1;
}

size_t GltfSceneBuilder::node(const std::string& name, long parent, const glm::dvec3& t, const glm::dquat& r, const glm::dvec3& s) {
    json n = {{"name", name}};
    if (t != glm::dvec3(0.0)) n["translation"] = {t.x, t.y, t.z};
    if (r != glm::dquat(1, 0, 0, 0)) n["rotation"] = {r.x, r.y, r.z, r.w};
    if (s != glm::dvec3(1.0)) n["scale"] = {s.x, s.y, s.z};
    doc_["nodes"].push_back(n);
    const size_t index = doc_["nodes"].size() - 1;
    if (parent < 0) doc_["scenes"][0]["nodes"].push_back(index);
    else doc_["nodes"][size_t(parent)]["children"].push_back(index);
    return index;
}

void GltfSceneBuilder::setMesh(size_t node, size_t mesh) { doc_["nodes"][node]["mesh"] = mesh; }
void GltfSceneBuilder::setExtras(size_t node, const json& extras) { doc_["nodes"][node]["extras"] = extras; }

void GltfSceneBuilder::setLight(size_t node, const json& light) {
    json& lights = doc_["extensions"]["KHR_lights_punctual"]["lights"];
    lights.push_back(light);
    doc_["nodes"][node]["extensions"]["KHR_lights_punctual"]["light"] = lights.size() - 1;
    doc_["extensionsUsed"] = json::array({"KHR_lights_punctual"});
}

json GltfSceneBuilder::finished(bool embed) const {
    json d = doc_;
    json buffer = {{"byteLength", bin_.size()}};
    if (embed) buffer["uri"] = "data:application/octet-stream;base64," + base64(bin_);
    d["buffers"] = json::array({buffer});
    return d;
}

std::string GltfSceneBuilder::gltf() const { return finished(true).dump(1) + "\n"; }

std::string GltfSceneBuilder::glb() const {
    std::string text = finished(false).dump();
    while (text.size() % 4) text += ' ';
    std::string bin = bin_;
    while (bin.size() % 4) bin += '\0';
    std::string out = "glTF";
    appendU32(out, 2);
    appendU32(out, uint32_t(12 + 8 + text.size() + 8 + bin.size()));
    appendU32(out, uint32_t(text.size()));
    appendU32(out, 0x4E4F534A);
    out += text;
    appendU32(out, uint32_t(bin.size()));
    appendU32(out, 0x004E4942);
    return out + bin;
}

GltfSceneBuilder::Primitive cubePrimitive(const glm::vec3& c, float side, long material) {
    GltfSceneBuilder::Primitive p;
    p.material = material;
    const float h = side / 2;
    for (int k = 0; k < 8; ++k) p.positions.push_back(c + glm::vec3(k & 1 ? h : -h, k & 2 ? h : -h, k & 4 ? h : -h));
    // Each face: the four corners with one coordinate fixed, as two triangles facing out.
    for (int axis = 0; axis < 3; ++axis)
        for (int sign = 0; sign < 2; ++sign) {
            std::vector<uint32_t> q;
            for (uint32_t k = 0; k < 8; ++k)
                if (((k >> axis) & 1u) == uint32_t(sign)) q.push_back(k);
            glm::vec3 out(0.0f);
            out[axis] = sign ? 1.0f : -1.0f;
            // q holds the face's corners in bit order: q0 and q3 are opposite.
            addOriented(p.indices, p.positions, q[0], q[1], q[3], out);
            addOriented(p.indices, p.positions, q[0], q[3], q[2], out);
        }
    return p;
}

GltfSceneBuilder::Primitive squarePrimitive(float half, float y, float cx, float cz, long material) {
    GltfSceneBuilder::Primitive p;
    p.material = material;
    p.positions = {{cx - half, y, cz - half}, {cx + half, y, cz - half}, {cx + half, y, cz + half}, {cx - half, y, cz + half}};
    addOriented(p.indices, p.positions, 0, 1, 2, {0, 1, 0});
    addOriented(p.indices, p.positions, 0, 2, 3, {0, 1, 0});
    p.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    return p;
}

glm::dquat aimMinusZ(const glm::dvec3& direction) {
    // Half-way quaternion: (1 + a.b, a x b), normalised (a and b are not opposite here).
    const glm::dvec3 a(0, 0, -1), b = glm::normalize(direction);
    const glm::dvec3 axis = glm::cross(a, b);
    return glm::normalize(glm::dquat(1.0 + glm::dot(a, b), axis.x, axis.y, axis.z));
}

namespace {

// The root every known scene hangs under: identity, or (`moved`) 100 km away and turned by
// 37 degrees.
long worldRoot(GltfSceneBuilder& b, bool moved) {
    return long(b.node("World", -1, moved ? glm::dvec3(100000.0, 0.0, -100000.0) : glm::dvec3(0.0),
                       moved ? glm::angleAxis(glm::radians(37.0), glm::dvec3(0, 1, 0)) : glm::dquat(1, 0, 0, 0)));
}

// The known scenes' sun (the first light, bit 0): a directional light on a node over the
// origin, tilted.
void addSun(GltfSceneBuilder& b, long world) {
    const size_t sun = b.node("Sun", world, glm::dvec3(0, 50, 0), aimMinusZ({0.3, -1.0, 0.2}));
    b.setLight(sun, {{"type", "directional"}, {"name", "sun"}, {"intensity", 3.0}});
}

// A node `name` under `parent` that draws `mesh`.
size_t placeMesh(GltfSceneBuilder& b, const std::string& name, size_t mesh, long parent, const glm::dvec3& t,
                 const glm::dquat& r = glm::dquat(1, 0, 0, 0), const glm::dvec3& s = glm::dvec3(1.0)) {
    const size_t n = b.node(name, parent, t, r, s);
    b.setMesh(n, mesh);
    return n;
}

}  // namespace

KnownGltfScene courtyardScene(bool moved) {
    KnownGltfScene k;
    k.name = moved ? "courtyard-moved" : "courtyard";
    GltfSceneBuilder& b = k.scene;
    const long world = worldRoot(b, moved);
    // Lights, in bit order: sun (bit 0), lamp (bit 1), torch (bit 2).
    addSun(b, world);
    const size_t lamp = b.node("Lamp", world, glm::dvec3(20, 3, 20));
    b.setLight(lamp, {{"type", "point"}, {"name", "lamp"}, {"range", 6.0}, {"intensity", 50.0}});
    b.setExtras(lamp, {{"shadowcull_bias", 0.02}});
    const size_t torch = b.node("Torch", world, glm::dvec3(-20, 8, -20), aimMinusZ({0.1, -1.0, 0.05}));
    b.setLight(torch, {{"type", "spot"}, {"name", "torch"}, {"range", 20.0}, {"spot", {{"outerConeAngle", 0.5}}}});
    k.lightNames = {"sun", "lamp", "torch"};

    const long leaves = long(b.material("leaves", true, true));
    const long bark = long(b.material("bark", false, false));
    const size_t cube = b.mesh("Cube", {cubePrimitive()});
    const size_t ground = b.mesh("Ground", {squarePrimitive(30.0f)});
    const size_t shelf = b.mesh("Shelf", {squarePrimitive(3.0f)});
    const size_t bush = b.mesh("Bush", {cubePrimitive({0, 0.55f, 4}, 1.0f, bark), squarePrimitive(5.0f, 4.0f, 0, 0, leaves)});

    auto place = [&](const std::string& name, size_t mesh, long parent, const glm::dvec3& t, const glm::dquat& r = glm::dquat(1, 0, 0, 0),
                     const glm::dvec3& s = glm::dvec3(1.0)) { return placeMesh(b, name, mesh, parent, t, r, s); };
    // The ground's own shadow falls below it, where nothing is.
    place("Ground", ground, world, {0, 0, 0});
    k.expected["Ground"] = {0};
    place("Crate", cube, world, {0, 0.55, 0});  // sun only: the lamp and torch do not reach
    k.expected["Crate"] = {1};
    place("LampPost", cube, world, {21, 0.55, 20});  // sun and lamp
    k.expected["LampPost"] = {3};
    place("SpotTarget", cube, world, {-19.2, 0.55, -19.6});  // on the torch's axis: sun and torch
    k.expected["SpotTarget"] = {5};
    place("HighCube", cube, world, {-40, 20, 40});  // its shadow lands beyond the ground
    k.expected["HighCube"] = {0};
    // Hierarchy: (20,0,0) + R_y(180) * 2 * (22.5,5,0) = (-25,10,0), over the ground. Without
    // the parent's rotation the cube would hang at (65,10,0), over nothing.
    const long rig = long(b.node("Rig", world, {20, 0, 0}, glm::angleAxis(glm::radians(180.0), glm::dvec3(0, 1, 0)), glm::dvec3(2.0)));
    place("RigCube", cube, rig, {22.5, 5, 0});
    k.expected["RigCube"] = {1};
    // A one-sided shelf facing up, placed with a mirroring scale: it still faces up, so it
    // receives the shadow of the cube above it (were it flipped, nothing would).
    place("Shelf", shelf, world, {45, 5, -45}, glm::dquat(1, 0, 0, 0), {-1, 1, 1});
    k.expected["Shelf"] = {0};
    place("ShelfCaster", cube, world, {44, 10, -46});
    k.expected["ShelfCaster"] = {1};
    // A bush: an opaque trunk and an alpha-masked canopy at 4 m. Light passes the canopy,
    // so the trunk and the flower under it are lit and shadow the ground.
    place("Bush", bush, world, {10, 0, 10});
    k.expected["Bush"] = {1, 1};
    place("Flower", cube, world, {10, 0.55, 10});
    k.expected["Flower"] = {1};
    // The engine never draws its shadow: every bit 0.
    const size_t quiet = place("NoShadowCube", cube, world, {-5, 0.55, 5});
    b.setExtras(quiet, {{"shadowcull_casts_shadow", false}});
    k.expected["NoShadowCube"] = {0};
    return k;
}

KnownGltfScene nonCasterScene(bool moved) {
    KnownGltfScene k;
    k.name = moved ? "non-casters-moved" : "non-casters";
    GltfSceneBuilder& b = k.scene;
    const long world = worldRoot(b, moved);
    addSun(b, world);
    k.lightNames = {"sun"};
    const size_t cube = b.mesh("Cube", {cubePrimitive()});
    const size_t ground = b.mesh("Ground", {squarePrimitive(30.0f)});
    const size_t slab = b.mesh("Slab", {cubePrimitive(glm::vec3(0.0f), 1.0f)});  // scaled into a slab
    auto place = [&](const std::string& name, size_t mesh, const glm::dvec3& t, const glm::dvec3& s = glm::dvec3(1.0)) {
        return placeMesh(b, name, mesh, world, t, glm::dquat(1, 0, 0, 0), s);
    };
    place("Ground", ground, {0, 0, 0});
    k.expected["Ground"] = {0};
    // Traced back towards the sun, every point of a cube at (x, 0.05..1.05, z) crosses
    // y = 3 within 1 m of (x - 0.6, z - 0.4): inside a 6 m roof centred above it.
    place("OpenCube", cube, {-10, 0.55, 0});
    const size_t glass = place("GlassRoof", slab, {-10, 3.1, 0}, {6, 0.2, 6});
    b.setExtras(glass, {{"shadowcull_casts_shadow", false}});
    k.expected["OpenCube"] = {1};
    k.expected["GlassRoof"] = {0};
    place("HiddenCube", cube, {10, 0.55, 0});
    place("SolidRoof", slab, {10, 3.1, 0}, {6, 0.2, 6});
    k.expected["HiddenCube"] = {0};
    k.expected["SolidRoof"] = {1};
    // A cube floating 6 m over a floor that casts no shadow, beyond the ground's edge
    // (z 30): nothing but the floor below it. Its rays land on the floor's top within
    // x 1.3..2.6, z 43.7..44.9 (floor: x -4..4, z 41..49): it receives, so the cube is 1.
    const size_t floor = place("GlassFloor", slab, {0, 3.1, 45}, {8, 0.2, 8});
    b.setExtras(floor, {{"shadowcull_casts_shadow", false}});
    place("FloatingCube", cube, {0, 9.5, 43});
    k.expected["GlassFloor"] = {0};
    k.expected["FloatingCube"] = {1};
    return k;
}

}  // namespace shadowcull::testing
