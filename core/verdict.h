// The verdict table: per centre-chunk object, primitive group and light, whether the
// shadow matters (kept), provably does not (culled), or nobody could tell yet
// (undecided, written as 1). Each decision records the stage and its evidence.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/scene.h"
#include "core/status.h"

namespace shadowcull {

enum class Verdict : uint8_t { Undecided, Kept, Culled };

const char* verdictName(Verdict v);

// A ray that proves a 1: from `wsOrigin` along `wsDirection`, the first opaque surface is
// the group at `wsP`, and `wsQ` on `receiver` lies behind it by more than the bias and
// receives light. World coordinates (metres).
struct Witness {
    glm::dvec3 wsOrigin{0.0}, wsDirection{0.0}, wsP{0.0}, wsQ{0.0};
    std::string receiver;  // label of the receiving object, with its group
};

struct Decision {
    Verdict verdict = Verdict::Undecided;
    std::string stage;   // "input", "reach", "raycast", ... (empty while undecided)
    std::string reason;  // the proof for a 0, or a note for a 1
    std::optional<Witness> witness;
};

// Verdicts of one centre-chunk object (model or terrain), one row per group.
struct ObjectVerdicts {
    int elementIndex = 0;   // among the chunk root's model/terrain children
    int windowObject = -1;  // index into BakeWindow::objects; -1 when the object was skipped
    bool terrain = false;
    std::string uuid;
    int groupCount = 0;
    std::vector<Decision> decisions;  // [group * lightCount + light]
};

struct ChunkVerdicts {
    ChunkCoord coord;
    std::string path;
    int lightCount = 0;
    std::vector<ObjectVerdicts> objects;  // every model/terrain element, in document order
    std::vector<std::string> simulated;   // effects the bake simulated for this chunk

    Decision& at(size_t object, int group, int light) {
        return objects[object].decisions[size_t(group) * size_t(lightCount) + size_t(light)];
    }
    const Decision& at(size_t object, int group, int light) const {
        return objects[object].decisions[size_t(group) * size_t(lightCount) + size_t(light)];
    }
    // Bit l is 1 unless (group, light l) was proved 0: undecided is written as 1.
    uint32_t groupMask(size_t object, int group) const;
};

// Every stage turns undecided into kept or culled and never changes a decided bit; this is
// the one place that writes a decision.
void decide(Decision& d, Verdict v, const char* stage, std::string reason, std::optional<Witness> witness = std::nullopt);

}  // namespace shadowcull
