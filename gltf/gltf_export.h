// `shadowcull export`: a bake's masks back into the glTF scene the space was imported
// from (docs/format.md, "glTF scenes"). Every node that got verdicts gets
// extras.shadowcull = {"mask": M, "groups": [m0, m1, ...]} (one mask per primitive of its
// mesh, bit i for light i); the root gets extras.shadowcull.lights = [{"node", "name",
// "type", "bias", "slopeBias", "filterRadius", "normalBias", and "range", "coneAngle",
// "direction" where they apply}] in bit order: the light parameters the masks were baked
// for, which an engine's shadow pass must use for the masks to hold. Nothing else in the
// file changes: JSON keys keep their order, binary chunks are copied byte for byte.
#pragma once

#include <string>

#include "util/status.h"

namespace shadowcull::gltf {

struct ExportOptions {
    std::string spaceDir;     // the space `shadowcull import` wrote (its space.xml names the scene)
    std::string resultsPath;  // a bake's --results JSON of that space
    std::string scenePath;    // the glTF the space was imported from (or an earlier export of it)
    std::string outPath;      // .glb for a .glb scene, .gltf for a .gltf scene
};

struct ExportReport {
    size_t nodes = 0;       // nodes given masks
    size_t primitives = 0;  // primitive masks written
    size_t culledBits = 0;  // 0 bits among them
    size_t bits = 0;        // all bits among them
    size_t lights = 0;
    size_t unbakedNodes = 0;  // mesh nodes of the space whose chunk the results do not hold
};

Expected<ExportReport> exportMasks(const ExportOptions& options);

}  // namespace shadowcull::gltf
