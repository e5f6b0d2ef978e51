// One light of the conservative confirmation (confirm_stage.h), in the order it runs: the
// bits to examine, the light's views, the casters' cells per view, the surfaces near the
// casters, then per view the pieces and the three passes, and last the counts and pixels
// read back into decisions. Private to the stage's translation units: the preparation is
// in confirm_light.cpp, the passes and the results (beside the proof) in confirm_stage.cpp.
#pragma once

#include <cstdint>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "gpu/confirm_gl.h"
#include "gpu/confirm_stage.h"
#include "gpu/confirm_surfaces.h"
#include "gpu/conservative.h"
#include "gpu/gl_api.h"
#include "gpu/light_view.h"
#include "gpu/pixel_cells.h"
#include "gpu/selection_tree.h"

namespace shadowcull::gpu {

// Per run: the stage's trees and edges per mesh.
struct GpuConfirmStage::LightWork {
    std::unordered_map<const Mesh*, std::unique_ptr<SelectionTree>>& trees;
    std::unordered_map<const Mesh*, std::unique_ptr<MeshEdges>>& edges;
    const SelectionTree& treeOf(const Mesh* mesh) {
        auto& t = trees[mesh];
        if (!t) t = std::make_unique<SelectionTree>(*mesh);
        return *t;
    }
    const MeshEdges& edgesOf(const Mesh* mesh) {
        auto& e = edges[mesh];
        if (!e) e = std::make_unique<MeshEdges>(*mesh, treeOf(mesh).triangles());
        return *e;
    }
};

// The state of one light's confirmation, filled step by step (GpuConfirmStage::runLight).
struct GpuConfirmStage::LightRun {
    struct Caster {
        uint32_t object, triangle, id;
    };

    // One light view's set-up: the casters' pieces and the cells they reach.
    struct ViewPrep {
        PieceBuilder pb;
        CellMask mask;
        std::vector<RasterPiece> casterPieces;
        PixelRect roi = PixelRect::empty();
        double depthEps = 0;  // metres, the shader's absolute depth margin
        float dilatePx = 0;   // receivers' dilation (directional light with a filter radius)
        bool skip = false;    // no caster in this view
        ViewPrep(const LightView& view, double nearZ, bool all) : pb(view, nearZ), mask(view.width, view.height, all) {}
        // No piece made from anything within the hull of pts can reach a caster cell (so
        // keepTouching would drop them all).
        bool misses(const glm::dvec3* pts, size_t n, float dilate) const {
            if (pb.clipsAway(pts, n)) return true;
            const std::optional<PixelRect> r = hullReach(pts, n, pb, dilate);
            return r && !mask.touches(*r);
        }
        bool missesTriangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, float dilate) const {
            const glm::dvec3 pts[3] = {a, b, c};
            return misses(pts, 3, dilate);
        }
    };

    // An occluder sheet's pieces in one view, with the pixel rectangle its fragments can reach.
    struct SheetPieces {
        std::vector<RasterPiece> pieces;
        PixelRect rect;
    };

    // One object's pieces in one view.
    struct ObjectPieces {
        std::vector<SheetPieces> sheets;
        std::vector<RasterPiece> receivers;
    };

    // A view's pieces in Gl::all, in drawing order: the occluder batches, the receivers,
    // the casters. Ranges are (first, count) in pieces, or in vertices of `rects`.
    struct ViewDraw {
        std::vector<std::pair<GLint, GLsizei>> batchRange, batchRects;
        std::vector<float> rects;  // each sheet's pixel rectangle, two triangles, per batch
        GLint recvFirst = 0, castFirst = 0, end = 0;
        int sheets = 0, batches = 0;
    };

    // Which passed pixels are recorded (Slots in kConfirmRasterFs). The shader's atomics
    // hand out record slots in the order the rasteriser's threads run the fragments, so
    // when a query's fragments do not all fit, "the first ones" would differ from run to
    // run (and with them the dense witness search and the results JSON). Instead, per
    // view, every passed pixel is recorded while they fit in the query's free records;
    // when they do not, the records are written again for the pixels whose hash is under a
    // threshold, lowered until they fit: a set that depends on the pixels alone.
    struct Slot {
        uint32_t threshold, base, room, offered;
    };
    static_assert(sizeof(Slot) == 16, "one uvec4 per query");
    static constexpr uint32_t kAllPixels = 0xffffffffu;

    LightRun(GpuConfirmStage& stage, const BakeWindow& w, ChunkVerdicts& cv, int l, LightWork& work, StageStats& stats);

    // Preparation (confirm_light.cpp).
    bool selectBits();      // the undecided bits of light l; false: none
    bool frameViews();      // views, near plane and bias; false: nothing can be proved
    void findCasters();     // the examined groups' triangles within reach
    void maskViews();       // per view, the casters' pieces and the cells they reach
    void findSurfaces();    // occluder sheets and receivers of the objects near the casters
    std::vector<ObjectPieces> viewPieces(size_t vi) const;
    // Passes and results (confirm_stage.cpp).
    Status prepareRecords();
    Status drawView(size_t vi);
    Status readResults();

    GpuConfirmStage& stage;
    Gl& gpu;  // the stage's programs, render targets and buffers
    const GlApi& gl;
    const BakeWindow& w;
    ChunkVerdicts& cv;
    const int l;
    const Light& L;
    const bool persp;  // point or spot light: perspective views
    const int res;     // pixels per side of each view
    LightWork& work;
    StageStats& stats;

    std::vector<std::vector<int>> queryOf;  // per window object, per group: query id, or -1
    std::vector<GroupPixels> queries;       // the bits examined, by query id
    std::vector<LightView> views;
    double nearZ = 0;          // perspective: a near plane below all geometry
    bool anyReceiver = false;  // receivers not bounded: only "never lit" can be proved
    double biasEff = 0;        // the bias along the view's axis (bias' of the proof)
    std::vector<Caster> casters;  // by object, then by triangle
    std::vector<ViewPrep> preps;  // per view
    std::vector<uint32_t> near;   // window objects with triangles over a caster cell
    std::vector<std::vector<uint32_t>> nearTriangles;  // per near object, ascending
    std::vector<ObjectSurfaces> surfaces;              // per near object
    uint32_t cap = 0;                     // records per query
    std::vector<Slot> slots;              // per query
    std::vector<uint32_t> recordsWritten; // per query, over the views so far

private:
    // Window-local vertices, computed where they are needed (the same bits as
    // WindowTriangles): the stage looks at few of a dense neighbour's triangles.
    glm::dvec3 position(uint32_t object, uint32_t vertex) const {
        const WindowObject& o = w.objects[object];
        return o.lsTransform.apply(o.mesh->positions[vertex]);
    }
    bool findNearPlane();
    void maskView(const LightView& view, ViewPrep& vp);
    void objectPieces(size_t i, const ViewPrep& vp, const LightView& view, ObjectPieces& out) const;
    bool sheetPieces(const Sheet& s, const ViewPrep& vp, const LightView& view, SheetPieces& p) const;
    ViewDraw packView(const ViewPrep& vp, std::vector<ObjectPieces>& pieces);
    void setUpView(size_t vi, const ViewDraw& d);
    void drawOccluders(const ViewDraw& d);
    void drawReceivers(const ViewDraw& d);
    void drawCasters(const ViewDraw& d);
    void drawPieces(GLint first, GLsizei count) const;
    void uploadSlots();
    bool settleSlots();
    Status finishView(size_t vi, const ViewDraw& d);
    void passedPixels(GroupPixels& gp, size_t q, const std::vector<uint32_t>& records) const;
    void decideBit(GroupPixels& gp, const std::string& at);
};

}  // namespace shadowcull::gpu
