// The verdict table: per centre-chunk object, primitive group and light, whether the
// shadow matters (kept), provably does not (culled), or nobody could tell yet
// (undecided, written as 1). Each decision records the stage and its evidence.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "core/scene.h"
#include "util/status.h"

namespace shadowcull {

enum class Verdict : uint8_t { Undecided, Kept, Culled };

const char* verdictName(Verdict v);

namespace reasons {
// The reason the reach stage gives for a caster the engine never draws into a shadow map.
// One text, so that the stage and the reports that classify it (cli/savings.h) cannot
// drift apart.
inline constexpr char kCastsShadowFalse[] = "castsShadow is false";
}  // namespace reasons

// A ray that proves a 1: from `wsOrigin` along `wsDirection`, the first opaque surface is
// the group at `wsP`, and `wsQ` on `receiver` lies behind it by more than the bias and
// receives light. World coordinates (metres).
struct Witness {
    glm::dvec3 wsOrigin{0.0}, wsDirection{0.0}, wsP{0.0}, wsQ{0.0};
    std::string receiver;  // label of the receiving object, with its group
    // World box of the receiving object (min > max: unknown), for pictures of the witness.
    glm::dvec3 wsReceiverMin{1e300}, wsReceiverMax{-1e300};
};

// What a decision rests on beyond a fixed sentence: a reason with numbers in it, or a
// witness ray. Kept on the heap, only for the decisions that have one.
// What a stage saw on a bit it could not decide (the receiver the shadow volume could not
// exclude, the pixels that passed), so a user can tell a hard case from a missing proof.
struct StageNote {
    std::string_view stage;  // static text (Stage::name())
    std::string text;
};

struct Evidence {
    std::string reason;
    std::optional<Witness> witness;
    std::vector<StageNote> notes;  // undecided bits only: deciding a bit replaces its evidence
};

// One bit's decision. Small (48 bytes), because a bake keeps one per (group, light) of the
// whole world: the stage and most reasons are fixed sentences (static storage, not copied);
// only computed reasons and witnesses take heap space.
class Decision {
public:
    Verdict verdict = Verdict::Undecided;
    std::string_view stage;  // "input", "reach", "raycast", ... (empty while undecided)

    // The proof for a 0, or a note for a 1 (empty while undecided).
    std::string_view reason() const {
        return evidence_ ? std::string_view(evidence_->reason) : staticReason_ ? staticReason_ : std::string_view();
    }
    // The ray that proves a 1, when a stage found one.
    const Witness* witness() const { return evidence_ && evidence_->witness ? &*evidence_->witness : nullptr; }
    // Notes of the stages that looked at the bit and left it undecided (none once decided).
    const std::vector<StageNote>& notes() const;

private:
    const char* staticReason_ = nullptr;
    std::shared_ptr<const Evidence> evidence_;  // shared: copies of a verdict table share it
    friend void decideWith(Decision&, Verdict, const char*, const char*, std::shared_ptr<const Evidence>);
    friend void addNote(Decision&, const char*, std::string);
};

// Verdicts of one centre-chunk object (model or terrain), one row per group.
struct ObjectVerdicts {
    int elementIndex = 0;   // among the chunk root's model/terrain children
    int windowObject = -1;  // index into BakeWindow::objects; -1 when the object was skipped
    bool terrain = false;
    std::string uuid;
    int groupCount = 0;
    std::vector<Decision> decisions;  // [group * lightCount + light]
    // World box of each group's triangles ({min, max}; min > max for a group without any),
    // for reports that draw the object.
    std::vector<std::array<glm::dvec3, 2>> wsGroupBounds;
    // Placed triangles of each group (degenerate ones too: an engine draws them), for the
    // shadow-pass savings (cli/savings.h).
    std::vector<uint64_t> groupTriangles;
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

// Every stage turns undecided into kept or culled and never changes a decided bit; these
// are the only ways to write a decision. `stage` must be static text (Stage::name()).
// A fixed sentence (a string literal) is stored as a pointer:
template <size_t N>
void decide(Decision& d, Verdict v, const char* stage, const char (&reason)[N]);
// A computed reason, and a witness ray, go to the heap:
void decide(Decision& d, Verdict v, const char* stage, std::string reason, std::optional<Witness> witness = std::nullopt);
// Evidence that many bits share (made once, e.g. per light):
void decide(Decision& d, Verdict v, const char* stage, std::shared_ptr<const Evidence> shared);

void decideWith(Decision& d, Verdict v, const char* stage, const char* staticReason, std::shared_ptr<const Evidence> evidence);
// Records what `stage` saw on a bit it leaves undecided (ignored on a decided bit).
void addNote(Decision& d, const char* stage, std::string text);

template <size_t N>
void decide(Decision& d, Verdict v, const char* stage, const char (&reason)[N]) {
    decideWith(d, v, stage, reason, nullptr);
}

}  // namespace shadowcull
