// raycast/: witness rays with Embree 3. A witness proves a 1 (semantics.md): a ray from
// the light whose first opaque hit is on the group (p is lit) and behind which, farther
// than the bias (+ slope term), lies a receiver that receives light.
//
// The stage only ever proves 1s. Everything it cannot prove stays undecided (written as
// 1), so an error here can cost render time, never a shadow.
#pragma once

#include <array>
#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/stage.h"

namespace shadowcull::raycast {

struct RaycastOptions {
    int areaSamples = 256;         // area-weighted samples per group and light
    int maxFeatureSamples = 1024;  // vertex and edge-midpoint samples per group and light
    int maxHitsPerRay = 48;        // surfaces behind p examined per witness line
    int threads = 0;               // Embree build threads; 0 = all
    // Receiver-side search (receiver_targets.h): for a bit of a large caster still
    // undecided after its own samples, up to this many points on the receivers that may lie
    // in its shadow (0: off). A large caster: a terrain, or a group whose own area samples
    // are at least `largeCasterSpacing` metres apart.
    int receiverSamples = 2048;
    double largeCasterSpacing = 0.5;
};

// A witness search for one (group, light) — or every undecided light of the group when
// `light` is -1 — aimed at `targets` (window-local points on or near the group; empty: the
// group's own samples, see group_samples.h).
struct WitnessSearch {
    size_t object = 0;  // index into ChunkVerdicts::objects
    int group = 0;
    int light = -1;
    std::vector<glm::dvec3> targets;
    // With no targets: aim through the receivers in the group's shadow for `light`
    // (receiver_targets.h) instead of through the group's own samples.
    bool throughReceivers = false;
    // The group's own samples (no targets, not through receivers) from this index on: the
    // rest of a search whose first samples were traced before (RaycastStage::finishDeferred),
    // `litBefore` of them lit (for the note of a bit left undecided).
    size_t fromTarget = 0;
    size_t litBefore = 0;
    // A receiver triangle (window object, mesh triangle) the targets were aimed at: with a
    // normal bias, its moved copy is tested against every line too, besides the surfaces
    // the line hits (a lookup point off the surface lies on a line that may miss it).
    std::optional<std::array<uint32_t, 2>> receiver = std::nullopt;
};

class RaycastStage : public Stage {
public:
    explicit RaycastStage(RaycastOptions options = {});
    ~RaycastStage() override;
    RaycastStage(const RaycastStage&) = delete;
    RaycastStage& operator=(const RaycastStage&) = delete;

    const char* name() const override { return "raycast"; }
    // Builds the window's Embree scene (meshes once per resource, placed as instances;
    // terrain as triangles), then searches a witness for every undecided bit, in parallel
    // over groups (TBB; call it inside the task arena that sets the thread count); then,
    // for the bits of large casters still undecided, through the receivers in their shadow
    // (same scene, same witness test).
    Status run(const BakeWindow& window, ChunkVerdicts& verdicts, StageStats& stats) override;
    void forgetMeshes(const std::unordered_set<const Mesh*>& meshes) override;

    // A second, denser search where another stage says a witness may be (the pixels that
    // passed the GPU confirmation, the receivers the shadow volumes reach): same witness
    // test, other targets.
    // `reason`: the witness's reason (static text).
    Status searchAt(const BakeWindow& window, ChunkVerdicts& verdicts, std::vector<WitnessSearch> searches,
                    StageStats& stats, const char* reason = "witness ray where the GPU stage saw samples pass");

    // From keepScene(w) until dropScene(), every search on `w` traces the Embree scene the
    // first one builds (a window's later searches, after the geometry and GPU stages, each
    // rebuilt it: about 2 ms a time for a whole-space window of 2,000 objects). `w` must not
    // change in between. Without keepScene, each search builds its own.
    void keepScene(const BakeWindow& window);
    void dropScene();

    // The exact test before a terrain's long searches. From deferLongSearches(n) on, run()
    // traces only the first n of a terrain bit's own samples and leaves the bit undecided
    // without a note, and leaves every large caster's receiver-side search for later;
    // finishDeferred() then searches on from sample n (and through the receivers in its
    // shadow) for the bits still undecided. A bit ends with the same
    // witness either way (the first of the same samples in the same order), and one the
    // shadow volumes prove 0 in between has none: most of a terrain's bits, whose searches
    // trace thousands of lines that find nothing under the ground (docs/semantics.md,
    // "Stages run cheap to expensive"). n = 0 (the default): run() searches in full.
    void deferLongSearches(size_t firstTargets);
    // The rest of run()'s short searches on `window` (the same window, after the stages
    // between); a no-op when run() deferred none.
    Status finishDeferred(const BakeWindow& window, ChunkVerdicts& verdicts, StageStats& stats);

private:
    // Which search: run()'s (a terrain's own samples cut short when deferLongSearches
    // asked, then for a large caster still undecided the receivers in its shadow; every bit
    // counted examined), finishDeferred()'s (the rest of those, and the receivers; its bits
    // were counted by run()), or searchAt()'s (the given targets alone).
    enum class Pass { Stage, Deferred, At };
    Status search(const BakeWindow& window, ChunkVerdicts& verdicts, std::vector<WitnessSearch>& searches,
                  StageStats& stats, const char* reason, Pass which);
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace shadowcull::raycast
