// gpu/: conservative confirmation (semantics.md, "The stages": gpu/). For the bits still
// undecided after the geometry and ray stages, rasterise each light view so that zero
// samples passed PROVES the bit is 0:
//
//  - occluders are under-estimated: a pixel counts as blocked only where one connected
//    sheet of an object's opaque surface (front- or back-facing towards the light, joined
//    across shared edges) covers the whole pixel, and then at the farthest depth that
//    sheet can have over the pixel;
//  - the group and the receivers are over-estimated: every pixel whose square touches a
//    triangle gets a fragment (triangles enlarged by half a pixel diagonal, with an exact
//    separating-axis test per pixel), at the nearest depth the group / the farthest depth
//    the receivers can have over the pixel;
//  - a pixel passes for group g when g may be lit there (its nearest depth is not behind
//    the blocked depth) and a receiver may lie behind it by more than the bias.
// If no pixel of any view passes, no ray from the light meets a lit point of g with a
// receiver behind it: the bit is culled, with the reason (never lit, or nothing behind).
// Otherwise it stays undecided, and the pixels that passed are kept (passedPixels()) so
// the raycast stage can search there for a witness, more densely.
//
// What is left undecided on purpose (a false keep is fine, a false cull is a defect):
//  - a point or spot light touching the geometry (no near plane below all geometry);
//  - a point or spot light with filterRadius > 0: only "never lit" is proved (the lateral
//    reach of the filter in a perspective view is not bounded here);
//  - a window with skipped objects: only "never lit" is proved (a skipped object might
//    have been a receiver);
//  - a surface behind itself within one pixel: a sloped surface's farthest depth over a
//    pixel lies behind its own nearest depth, so "nothing behind" needs a bias larger
//    than a pixel's depth span plus the depth margins (~1e-6 of the view's depth range);
//    with bias 0 it is never proved (the geometry stage proves those exactly);
//  - occluders made of separate objects, or of pieces that do not share edges (a wall of
//    bricks, two slabs side by side): the pixels along their seams count as open.
// Slope bias only adds to the bias and is ignored (ignoring it admits more receivers);
// range is applied only to exclude receivers wholly out of range, the cone only through
// the view (a square frustum around it); the terrain rule only excludes receiver
// triangles that lie wholly under the lowest terrain sample around them by more than
// terrainTolerance.
//
// Cost: per light and view, the casters' pixels set a region (a bounding rectangle and
// 8 x 8 pixel cells) outside which nothing is drawn; only the triangles over those cells are
// classified and cut into pieces, found through a box tree per unique mesh (selection_tree.h,
// confirm_surfaces.h), so a dense neighbour costs what lies over the examined pixels, not
// its triangle count; receivers that lie nowhere behind a caster and occluder sheets that
// lie nowhere in front of one are left out, and so are sheets whose pixel box holds no
// whole pixel (they block nothing: pixel_cells.h, holdsWholePixel).
#pragma once

#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <glm/vec3.hpp>

#include "core/stage.h"

namespace shadowcull::gpu {

struct MeshEdges;     // gpu/conservative.h
class SelectionTree;  // gpu/selection_tree.h

struct GpuConfirmOptions {
    int resolution = 1024;         // pixels per side of each light view
    int maxPixelsPerGroup = 256;   // passed pixels kept per (group, light)
    bool collectViewStats = false; // draw whole views (no pruning) and read back coverage counts (tests)
    // Terrain groups span the whole view and are almost never proved here; leaving them out
    // (they stay undecided, kept) spares a window whose other bits are decided all passes.
    bool includeTerrain = false;
    // Occluder sheets whose pixel box holds no whole pixel are left out (pixel_cells.h,
    // holdsWholePixel: they block nothing). false: drawn anyway (tests compare the two).
    bool dropSliverSheets = true;
    // The triangles of an object near the casters are found through its mesh's tree (only
    // those over the examined pixels are classified and tested). false: every triangle of
    // the object is (tests compare the two: the same pieces are drawn).
    bool treeSelection = true;
    // runCloseUp's pixels per side (at most `resolution`: the passes share its buffers).
    int closeUpResolution = 512;
};

// A pixel where the group may be lit with a receiver behind: the light ray through the
// pixel centre and the group's nearest possible depth there.
struct PassedPixel {
    glm::dvec3 lsPoint{0.0};      // window-local: pixel centre ray at the group's nearest depth
    glm::dvec3 lsDirection{0.0};  // unit, the way light travels along that ray
    double footprint = 0.0;       // pixel size in metres at that depth (search radius)
    int view = 0;                 // index into the light's views (gpu/light_view.h)
    int px = 0, py = 0;
};

// Outcome for one undecided bit the stage examined.
struct GroupPixels {
    size_t object = 0;  // index into ChunkVerdicts::objects
    int group = 0;
    int light = 0;
    uint64_t litSamples = 0;     // fragments where the group may be lit
    uint64_t passedSamples = 0;  // ... and a receiver may lie behind (0: culled)
    std::vector<PassedPixel> pixels;  // up to maxPixelsPerGroup, deduplicated
};

// Coverage of one light view (with collectViewStats).
struct ConfirmViewStats {
    int light = 0;
    int view = 0;
    int occluderPixels = 0;  // pixels blocked whole by some occluder sheet
    int receiverPixels = 0;  // pixels some receiver may reach
    int occluderSheets = 0;  // connected opaque sheets drawn
    int batches = 0;         // occluder passes (sheets with disjoint pixel rectangles share one)
};

class GpuConfirmStage : public Stage {
public:
    explicit GpuConfirmStage(GpuConfirmOptions options = {});
    ~GpuConfirmStage() override;
    GpuConfirmStage(const GpuConfirmStage&) = delete;
    GpuConfirmStage& operator=(const GpuConfirmStage&) = delete;

    const char* name() const override { return "gpu"; }
    // GlContext::report() of the context the passes ran on ("" before the
    // first run that needed them).
    std::string glDescription() const;
    // Looks only at undecided bits; culls those it proves 0 (stage "gpu"), leaves the rest
    // undecided. The OpenGL context is made on the first call that has work; no context
    // is an ErrorKind::Internal error.
    Status run(const BakeWindow& window, ChunkVerdicts& verdicts, StageStats& stats) override;
    // The same proof again for the directional lights' bits still undecided, each view framed
    // on the casters examined (every ray through them; depths over the whole window) instead
    // of the window near the centre chunk: finer pixels where pixels are read, at more
    // fragments (docs/performance.md, "Receivers from the whole space"). Passed pixels and
    // decisions as run's; a bit it proves 0 says "framed on the casters".
    Status runCloseUp(const BakeWindow& window, ChunkVerdicts& verdicts, StageStats& stats);
    void forgetMeshes(const std::unordered_set<const Mesh*>& meshes) override;

    // Every bit the last run examined, with the pixels that passed (for the raycast stage).
    const std::vector<GroupPixels>& passedPixels() const { return groups_; }
    // Per light view coverage of the last run (only with collectViewStats).
    const std::vector<ConfirmViewStats>& viewStats() const { return viewStats_; }
    // Meshes whose edge adjacency the stage holds (those of the last window it drew).
    size_t meshesWithEdges() const { return edges_.size(); }
    // Meshes whose box tree the stage holds (likewise).
    size_t meshesWithTrees() const { return trees_.size(); }
    // Triangles classified (as occluders or receivers) in the last run, summed over its
    // lights: those the trees selected over the examined pixels.
    uint64_t trianglesClassified() const { return trianglesClassified_; }

private:
    struct Gl;
    struct LightWork;
    struct LightRun;  // one light's steps (gpu/confirm_light.h)
    Status ensureGl();
    Status runLight(const BakeWindow& w, ChunkVerdicts& cv, int light, LightWork& work, StageStats& stats);
    GpuConfirmOptions options_;
    std::unique_ptr<Gl> gl_;
    std::vector<GroupPixels> groups_;
    std::vector<ConfirmViewStats> viewStats_;
    uint64_t trianglesClassified_ = 0;
    bool closeUp_ = false;  // within runCloseUp
    // Per mesh of the last window, its edge adjacency, kept while the window slides (it keeps
    // most of its meshes). Keyed by the mesh's address, so one stage serves one loaded space
    // (as the raycast stage's caches do).
    std::unordered_map<const Mesh*, std::unique_ptr<MeshEdges>> edges_;
    // Per mesh of the last window, its triangles' box tree in mesh coordinates (every
    // instance's), kept likewise: the triangles that can reach the examined pixels are
    // found through it (gpu/selection_tree.h).
    std::unordered_map<const Mesh*, std::unique_ptr<SelectionTree>> trees_;
};

}  // namespace shadowcull::gpu
