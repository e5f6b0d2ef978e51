// `shadowcull import`: a glTF 2.0 scene (nodes, meshes, materials, KHR_lights_punctual)
// becomes a space in the scene format (../shared/spec/scene-format.md; the mapping is in
// docs/format.md, "glTF scenes").
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <optional>
#include <string>
#include <vector>

#include "core/scene.h"
#include "util/status.h"

namespace shadowcull::gltf {

// Illuminance (lux) at which a point or spot light without `range` is taken to end: the
// range becomes sqrt(intensity / cut-off) for intensity in candela (KHR_lights_punctual).
constexpr double kDefaultLightCutoffLux = 0.01;
// Default chunk side (metres) and the widest window that is chosen automatically to hold
// a whole scene (neighbours on each side).
constexpr double kDefaultChunkSize = 64.0;
constexpr int kMaxAutoNeighbours = 8;
// Neighbours for a scene too large for one window, when no object reaches farther.
constexpr int kLargeSceneNeighbours = 2;

struct SunAngles {
    double azimuthDeg = 0.0;    // compass direction of the sun: 0 = -Z (north), 90 = +X (east)
    double elevationDeg = 45.0; // above the horizon, (0, 90]
};

struct ImportOptions {
    std::string scenePath;  // .gltf or .glb
    std::string outDir;     // must not exist, or be an empty directory
    std::optional<size_t> scene;  // default: the file's default scene
    std::optional<SunAngles> sun;  // adds a directional light after the scene's lights
    // Shadow settings of every light (metres); a light node's extras override them.
    double bias = 0.0, slopeBias = 0.0, filterRadius = 0.0, normalBias = 0.0;
    std::optional<double> chunkSize;  // default kDefaultChunkSize
    std::optional<int> neighbours;    // default: chosen (see docs/format.md)
    double lightCutoffLux = kDefaultLightCutoffLux;
};

struct ImportReport {
    size_t nodes = 0;         // nodes of the scene visited
    size_t models = 0;        // <model> elements written (one per mesh node)
    size_t meshes = 0;        // unique mesh resources written
    size_t triangles = 0;     // placed triangles
    size_t chunks = 0;        // chunk files written
    size_t sceneLights = 0;   // lights from KHR_lights_punctual nodes
    size_t lights = 0;        // all lights (with --sun)
    double chunkSize = 0.0;
    int neighbours = 0;
    std::string layout;       // one sentence: what each window loads, and why
    std::vector<Diagnostic> warnings;
};

// Reads and checks the whole scene first; writes nothing unless all of it is good. The
// space is written into a new directory beside `outDir` and renamed into place, so that
// `outDir` holds either nothing or the complete space.
Expected<ImportReport> importScene(const ImportOptions& options);

// The uuid written for glTF node `node` ("474C5446-" = "GLTF", then the node index in hex)
// and back. Results map to nodes through it (shadowcull export).
std::string nodeUuid(size_t node, const std::string& name);
std::optional<size_t> nodeFromUuid(const std::string& uuid);

// A hash of the document that ignores what export adds (every extras.shadowcull): export
// refuses a scene whose hash differs from the one import recorded in space.xml.
std::string sceneIdentity(const nlohmann::json& gltf);

}  // namespace shadowcull::gltf
