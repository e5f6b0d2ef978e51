// glTF scenes with known answers, written by code: for `shadowcull import` / bake /
// `export` tests and for data/gltf-courtyard. Every expected mask follows from the geometry
// with margins of at least 5 cm (gltfpack's 14-bit quantization moves a vertex by at most
// a few millimetres), so the same masks hold after `gltfpack -c`.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

namespace shadowcull::testing {

// Assembles a glTF 2.0 document with one binary buffer.
class GltfSceneBuilder {
public:
    GltfSceneBuilder();
    // A material; returns its index. An alpha-masked material gets a base colour texture
    // with an alpha channel (a material with alpha 1 everywhere is opaque whatever its
    // alphaMode says, and gltfpack rightly drops its MASK).
    size_t material(const std::string& name, bool alphaMask, bool doubleSided);
    struct Primitive {
        std::vector<glm::vec3> positions;
        std::vector<uint32_t> indices;  // triangles, counter-clockwise from the front
        long material = -1;
        std::vector<glm::vec2> uvs;     // TEXCOORD_0, when textured
    };
    size_t mesh(const std::string& name, const std::vector<Primitive>& primitives);
    // A node (name, TRS); `parent` < 0: a root of scene 0. Returns its index.
    size_t node(const std::string& name, long parent, const glm::dvec3& translation = glm::dvec3(0.0),
                const glm::dquat& rotation = glm::dquat(1, 0, 0, 0), const glm::dvec3& scale = glm::dvec3(1.0));
    void setMesh(size_t node, size_t mesh);
    void setExtras(size_t node, const nlohmann::json& extras);
    // A KHR_lights_punctual light definition attached to `node`.
    void setLight(size_t node, const nlohmann::json& light);

    nlohmann::json& doc() { return doc_; }
    std::string glb() const;   // binary glTF
    std::string gltf() const;  // .gltf with the buffer as a data: URI

private:
    nlohmann::json finished(bool embed) const;
    nlohmann::json doc_;
    std::string bin_;
};

// Unit cube centred at the origin, closed, counter-clockwise outside.
GltfSceneBuilder::Primitive cubePrimitive(const glm::vec3& centre = glm::vec3(0.0f), float side = 1.0f, long material = -1);
// Square in the plane y = `y`, centred at (cx, cz), front facing +y.
GltfSceneBuilder::Primitive squarePrimitive(float half, float y = 0.0f, float cx = 0.0f, float cz = 0.0f, long material = -1);
// The rotation that turns -Z into `direction` (KHR_lights_punctual lights shine along -Z).
glm::dquat aimMinusZ(const glm::dvec3& direction);

struct KnownGltfScene {
    std::string name;
    GltfSceneBuilder scene;
    // Node name -> expected mask per primitive, bit i for light i (depth-first order).
    std::map<std::string, std::vector<uint32_t>> expected;
    std::vector<std::string> lightNames;  // bit order
};

// "courtyard": a sun, a lamp (point) and a torch (spot) on nodes; a ground, cubes on it,
// a cube whose shadow falls on nothing, a node hierarchy with rotation and scale, a
// mirrored one-sided shelf that must receive, alpha-masked leaves that must let light
// through, a node with extras.shadowcull_casts_shadow = false, instanced meshes.
// `moved`: the whole scene under a root 100 km away and turned by 37 degrees.
KnownGltfScene courtyardScene(bool moved = false);

// "non-casters": a sun, a ground, and objects that cast no shadow by
// extras.shadowcull_casts_shadow = false (the engine never draws them into its shadow map,
// so they block no light; semantics.md condition 1): a cube under such a roof (its shadow on
// the ground: 1), the same cube under a roof that casts (hidden: 0), and a floating cube over
// such a floor, which still receives (1). `moved` as for the courtyard.
KnownGltfScene nonCasterScene(bool moved = false);

}  // namespace shadowcull::testing
