// Conservative GPU confirmation (see confirm_stage.h for what is proved and what is left).
//
// The idea is the original tool's: occlusion-query shadow caster culling (D. Bittner,
// O. Mattausch, A. Silvennoinen, M. Wimmer, "Shadow Caster Culling for Efficient Shadow
// Mapping", I3D 2011) - draw the receivers' depth and count, then query each caster. Here
// every per-pixel quantity is a bound instead of a sample, so that "no sample passed" is a
// proof. Conservative rasterisation (over-estimation by the half pixel diagonal: a quad
// per triangle and a separating-axis test per pixel; depth bounds from the triangle's
// plane over the pixel square)
// follows J. Hasselgren, T. Akenine-Moller, L. Ohlsson, "Conservative Rasterization",
// GPU Gems 2, ch. 42, 2005.
//
// Why a pass that counts zero samples proves the bit is 0. Take any ray from the light
// with a lit point p on group g and a receiver point q behind it (semantics.md); it runs
// through some pixel square S of some view (views of a light cover every ray that can
// reach a point within range and cone; pixel squares are closed, so a ray on a border
// belongs to both pixels and to both cube faces). Then at S:
//  1. g's fragment exists: S touches p's triangle, and the quad drawn for the triangle with
//     the fragment shader's separating-axis test admits every pixel whose square (widened
//     by a margin above float rounding) touches the triangle.
//  2. zlo(S) <= depth(p): zlo is the minimum over S of the triangle's depth plane (an
//     affine function of pixel position: the depth itself orthographically, 1/z in
//     perspective), clamped by the vertices' depth range, minus margins.
//  3. zlo(S) <= D_occ(S): an occluder sheet P is recorded at S only when (a) a point of S
//     lies robustly inside one of P's triangles and (b) none of P's "crack" edges
//     touches S. A crack edge is one not shared by exactly two of P's triangles running it
//     in opposite directions; P's triangles all face the same way, so across any other
//     edge they lie on both sides, and the boundary of P's projected union lies on crack
//     edges. S is connected and meets no boundary, so it lies wholly inside the union:
//     the ray meets P within S, at a depth at most the maximum over P's triangles touching
//     S of their farthest depth over S. That maximum (plus margins) is what P records, and
//     D_occ is the minimum over sheets. No opaque hit on the ray comes before p (p is lit;
//     ties do not block), so D_occ(S) >= depth(p) >= zlo(S). g's own triangles may be part
//     of a sheet: the same holds. Alpha-tested groups and objects that cast no shadow
//     (light passes them, semantics.md condition 1) are never part of a sheet.
//  4. R_max(S) > zlo(S) + bias': q's triangle is a receiver triangle (faces the light or is
//     two-sided, not wholly out of range, not wholly under the terrain), touches S and
//     has a farthest depth over S of at least depth(q) > depth(p) + bias. In perspective,
//     depth is axial z and along one ray z differences are the distance differences times
//     cos(angle to the axis) >= 1/sqrt(1 + 2 t^2), so bias' = bias / sqrt(1 + 2 t^2).
// Hence the fragment passes. Zero passed fragments in every view means no such ray.

#include "gpu/confirm_stage.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <map>
#include <string>
#include <tuple>

#include "gpu/confirm_light.h"
#include "util/float_mode.h"
#include "util/format.h"
#include "util/stop_request.h"

namespace shadowcull::gpu {

namespace {

constexpr float kBig = 1e30f;

}  // namespace

GpuConfirmStage::GpuConfirmStage(GpuConfirmOptions options) : options_(options) {}
GpuConfirmStage::~GpuConfirmStage() = default;  // destroying the context frees its objects

void GpuConfirmStage::forgetMeshes(const std::unordered_set<const Mesh*>& meshes) {
    for (const Mesh* m : meshes) edges_.erase(m), trees_.erase(m);
}

std::string GpuConfirmStage::glDescription() const { return gl_ ? gl_->session->context->report() : std::string(); }

Status GpuConfirmStage::run(const BakeWindow& w, ChunkVerdicts& cv, StageStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
    groups_.clear();
    viewStats_.clear();
    trianglesClassified_ = 0;
    // Lights with an undecided bit this stage looks at.
    std::vector<bool> lights(size_t(cv.lightCount), false);
    for (const ObjectVerdicts& ov : cv.objects) {
        if (ov.terrain && !options_.includeTerrain) continue;
        for (size_t k = 0; k < ov.decisions.size(); ++k)
            if (ov.decisions[k].verdict == Verdict::Undecided) lights[k % size_t(cv.lightCount)] = true;
    }
    if (closeUp_)  // a close-up frames directional views only (local lights' views are fixed)
        for (size_t l = 0; l < lights.size(); ++l) lights[l] = lights[l] && w.lsLights[l].type == LightType::Directional;
    if (std::none_of(lights.begin(), lights.end(), [](bool b) { return b; })) return Status::ok();
    // The pieces are computed on this thread and on TBB's workers, which Embree's builds
    // leave with flush-to-zero and denormals-are-zero: one mode everywhere, so that the GL
    // input does not depend on which thread made which piece (nor on the thread count).
    const FloatModeScope ieee(FloatModeScope::Underflow::Gradual);
    if (Status s = ensureGl(); !s) return s;
    GpuTimer gpuTime(gl_->session->gl);
    // The window slid: keep the edges of the meshes still loaded, drop the others (the
    // terrains of the chunks left behind), so that memory follows the window, not the world.
    const std::unordered_set<const Mesh*> loaded = w.meshes();
    for (auto it = edges_.begin(); it != edges_.end();) it = loaded.count(it->first) ? std::next(it) : edges_.erase(it);
    for (auto it = trees_.begin(); it != trees_.end();) it = loaded.count(it->first) ? std::next(it) : trees_.erase(it);
    LightWork work{trees_, edges_};
    for (int l = 0; l < cv.lightCount; ++l) {
        if (!lights[size_t(l)]) continue;
        const size_t first = groups_.size();
        if (Status s = runLight(w, cv, l, work, stats); !s) return s;
        for (size_t k = first; k < groups_.size(); ++k) {
            ++stats.bitsExamined;
            if (cv.at(groups_[k].object, groups_[k].group, l).stage == name()) ++stats.provedCulled;
        }
    }
    gpuTime.addTo(stats);
    stats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Status::ok();
}

Status GpuConfirmStage::runCloseUp(const BakeWindow& w, ChunkVerdicts& cv, StageStats& stats) {
    closeUp_ = true;
    const Status s = run(w, cv, stats);
    closeUp_ = false;
    return s;
}

// One light: its bits, its views, the casters' cells per view, the surfaces near them, then
// per view the occluder, receiver and caster passes, and the counts read into decisions.
Status GpuConfirmStage::runLight(const BakeWindow& w, ChunkVerdicts& cv, int l, LightWork& work, StageStats& stats) {
    LightRun lightRun(*this, w, cv, l, work, stats);
    if (!lightRun.selectBits() || !lightRun.frameViews()) return Status::ok();
    lightRun.findCasters();
    lightRun.maskViews();
    lightRun.findSurfaces();
    if (Status s = lightRun.prepareRecords(); !s) return s;
    for (size_t vi = 0; vi < lightRun.views.size(); ++vi) {
        // A point light's six views take seconds on a large window: a signal stops between them.
        if (Status s = stopStatus(); !s) return s;
        if (Status s = lightRun.drawView(vi); !s) return s;
    }
    return lightRun.readResults();
}

// Storage for the query results, accumulated over the views: per query two counts and
// `cap` records of a passed pixel.
Status GpuConfirmStage::LightRun::prepareRecords() {
    const size_t Q = queries.size();
    // Pixels kept per group: as asked, within the storage block limit (the counts are
    // exact whatever the cap).
    const uint64_t fit = uint64_t(std::min<GLint64>(gpu.maxStorageBlock, GLint64(256) << 20)) / (16 * uint64_t(Q));
    cap = uint32_t(std::max<uint64_t>(1, std::min<uint64_t>(uint64_t(std::max(1, stage.options_.maxPixelsPerGroup)), fit)));
    if (uint64_t(Q) * 2 * 4 > uint64_t(gpu.maxStorageBlock) || fit == 0)
        return makeError(ErrorKind::Internal, "", 0,
                         "too many undecided groups (" + std::to_string(Q) + ") for one GPU storage block");
    std::vector<uint32_t> zeros(2 * Q, 0);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gpu.ssbo[0]);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(zeros.size() * 4), zeros.data(), GL_DYNAMIC_COPY);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gpu.ssbo[1]);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(Q * cap * 16), nullptr, GL_DYNAMIC_COPY);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    slots.resize(Q);
    recordsWritten.assign(Q, 0);
    return Status::ok();
}

void GpuConfirmStage::LightRun::uploadSlots() {
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gpu.ssbo[2]);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(slots.size() * sizeof(Slot)), slots.data(), GL_DYNAMIC_COPY);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
}

// After a caster pass: the queries whose offered pixels fit are done for this view;
// the others get a lower threshold. False when every query is done.
bool GpuConfirmStage::LightRun::settleSlots() {
    gl.MemoryBarrier(GL_ALL_BARRIER_BITS);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gpu.ssbo[2]);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(slots.size() * sizeof(Slot)), slots.data());
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    bool again = false;
    for (size_t q = 0; q < slots.size(); ++q) {
        Slot& sl = slots[q];
        if (sl.offered <= sl.room) {
            recordsWritten[q] += sl.offered;
            sl = {0, recordsWritten[q], 0, 0};  // nothing more in this view
        } else {
            // Aim at three quarters of the room (a pixel's fragments come and go
            // together); the threshold strictly falls, so this ends.
            const uint64_t span = sl.threshold == kAllPixels ? (uint64_t(1) << 32) : uint64_t(sl.threshold);
            sl.threshold = uint32_t(span * 3 * sl.room / (4 * uint64_t(sl.offered)));
            sl.offered = 0;
            again = true;
        }
    }
    return again;
}

// One view: its pieces, packed and uploaded, then the three passes (points 3, 4 and the
// caster query of the proof above).
Status GpuConfirmStage::LightRun::drawView(size_t vi) {
    if (preps[vi].skip) return Status::ok();
    std::vector<ObjectPieces> pieces = viewPieces(vi);
    const ViewDraw d = packView(preps[vi], pieces);
    setUpView(vi, d);
    drawOccluders(d);
    drawReceivers(d);
    drawCasters(d);
    return finishView(vi, d);
}

// The view's pieces into Gl::all: the occluder sheets by batch, the receivers, the casters.
GpuConfirmStage::LightRun::ViewDraw GpuConfirmStage::LightRun::packView(const ViewPrep& vp,
                                                                        std::vector<ObjectPieces>& pieces) {
    std::vector<SheetPieces> sp;
    for (ObjectPieces& op : pieces)
        for (SheetPieces& s : op.sheets) sp.push_back(std::move(s));
    // Batches: sheets whose rectangles are disjoint cannot touch the same pixel, so
    // they share one work pass and one resolve.
    std::vector<std::vector<size_t>> batches;
    for (size_t s = 0; s < sp.size(); ++s) {
        bool placed = false;
        for (auto& b : batches) {
            bool clash = false;
            for (size_t o : b)
                if (sp[o].rect.overlaps(sp[s].rect)) {
                    clash = true;
                    break;
                }
            if (!clash) {
                b.push_back(s);
                placed = true;
                break;
            }
        }
        if (!placed) batches.push_back({s});
    }
    // One allocation, kept from view to view: growing by doubling would copy every piece
    // again per view on windows of dense meshes (and fault in each new block).
    std::vector<RasterPiece>& all = gpu.all;
    all.clear();
    {
        size_t total = vp.casterPieces.size();
        for (const SheetPieces& s : sp) total += s.pieces.size();
        for (const ObjectPieces& op : pieces) total += op.receivers.size();
        all.reserve(total);
    }
    ViewDraw d;
    d.sheets = int(sp.size());
    d.batches = int(batches.size());
    for (const auto& b : batches) {
        const GLint first = GLint(all.size()), firstRect = GLint(d.rects.size() / 2);
        for (size_t s : b) {
            all.insert(all.end(), sp[s].pieces.begin(), sp[s].pieces.end());
            const PixelRect& r = sp[s].rect;
            const float x0 = float(r.x0), y0 = float(r.y0), x1 = float(r.x1), y1 = float(r.y1);
            d.rects.insert(d.rects.end(), {x0, y0, x1, y0, x1, y1, x0, y0, x1, y1, x0, y1});
        }
        d.batchRange.push_back({first, GLsizei(all.size()) - first});
        d.batchRects.push_back({firstRect, GLsizei(d.rects.size() / 2) - firstRect});
    }
    d.recvFirst = GLint(all.size());
    for (const ObjectPieces& op : pieces) all.insert(all.end(), op.receivers.begin(), op.receivers.end());
    d.castFirst = GLint(all.size());
    all.insert(all.end(), vp.casterPieces.begin(), vp.casterPieces.end());
    d.end = GLint(all.size());
    return d;
}

// Upload the pieces and set the programs' uniforms and the state the passes share.
void GpuConfirmStage::LightRun::setUpView(size_t vi, const ViewDraw& d) {
    const LightView& view = views[vi];
    const ViewPrep& vp = preps[vi];
    const std::vector<RasterPiece>& all = gpu.all;
    // The buffer holds the view's pieces and, after them, room for the caster pieces drawn
    // again (those that passed).
    gl.BindBuffer(GL_ARRAY_BUFFER, gpu.vbo);
    const size_t needed = all.size() + vp.casterPieces.size();
    if (needed > gpu.vboPieces) {
        gpu.vboPieces = needed + needed / 4;
        gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(gpu.vboPieces * sizeof(RasterPiece)), nullptr, GL_STREAM_DRAW);
    }
    gl.BufferSubData(GL_ARRAY_BUFFER, 0, GLsizeiptr(all.size() * sizeof(RasterPiece)), all.data());
    gl.BindBuffer(GL_ARRAY_BUFFER, gpu.rectVbo);
    gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(d.rects.size() * sizeof(float)), d.rects.data(), GL_STREAM_DRAW);
    for (GLuint p : {gpu.resolve, gpu.clear}) {
        gl.UseProgram(p);
        gl.Uniform2f(gl.uniform(p, "uSize"), float(view.width), float(view.height));
    }
    // Uniforms a pass's program does not use are gone from it (location -1: ignored).
    for (const GLuint prog : gpu.raster) {
        gl.UseProgram(prog);
        gl.Uniform2f(gl.uniform(prog, "uSize"), float(view.width), float(view.height));
        gl.Uniform1f(gl.uniform(prog, "uSizeMax"), float(std::max(view.width, view.height)));
        gl.Uniform1i(gl.uniform(prog, "uPerspective"), persp ? 1 : 0);
        gl.Uniform1f(gl.uniform(prog, "uDepthEps"), float(vp.depthEps));
        gl.Uniform1f(gl.uniform(prog, "uBias"), float(biasEff));
        gl.Uniform1i(gl.uniform(prog, "uAnyReceiver"), anyReceiver ? 1 : 0);
        gl.Uniform1ui(gl.uniform(prog, "uRecordCap"), cap);
        gl.Uniform1ui(gl.uniform(prog, "uView"), uint32_t(vi));
    }
    gl.Viewport(0, 0, view.width, view.height);
    gl.Enable(GL_SCISSOR_TEST);
    const PixelRect& roi = vp.roi;
    gl.Scissor(roi.x0, roi.y0, roi.x1 - roi.x0, roi.y1 - roi.y0);
    gl.Disable(GL_DEPTH_TEST);
    gl.Disable(GL_STENCIL_TEST);
    gl.Disable(GL_CULL_FACE);
    gl.Enable(GL_BLEND);
    gl.BlendFunc(GL_ONE, GL_ONE);
}

void GpuConfirmStage::LightRun::drawPieces(GLint first, GLsizei count) const {
    if (count > 0) gl.DrawArraysInstancedBaseInstance(GL_TRIANGLE_STRIP, 0, 4, count, GLuint(first));
}

// 1. Occluders: D_occ = min over sheets of the sheet's bound, where it is valid.
// Per batch: draw its sheets into the work buffer (max), resolve their rectangles
// into D_occ (min), and reset those rectangles for the next batch.
void GpuConfirmStage::LightRun::drawOccluders(const ViewDraw& d) {
    gl.BindFramebuffer(GL_FRAMEBUFFER, gpu.occ.fbo);
    const float far[4] = {kBig, 0, 0, 0};
    gl.ClearBufferfv(GL_COLOR, 0, far);
    gl.BindFramebuffer(GL_FRAMEBUFFER, gpu.work.fbo);
    const float none[4] = {-kBig, 0, 0, 0};
    gl.ClearBufferfv(GL_COLOR, 0, none);
    for (size_t b = 0; b < d.batchRange.size(); ++b) {
        gl.BindFramebuffer(GL_FRAMEBUFFER, gpu.work.fbo);
        gl.Enable(GL_BLEND);
        gl.BlendEquation(GL_MAX);
        gl.UseProgram(gpu.raster[Gl::kOccluders]);
        gl.BindVertexArray(gpu.vao);
        drawPieces(d.batchRange[b].first, d.batchRange[b].second);
        gl.BindFramebuffer(GL_FRAMEBUFFER, gpu.occ.fbo);
        gl.BlendEquation(GL_MIN);
        gl.UseProgram(gpu.resolve);
        gl.ActiveTexture(GL_TEXTURE0);
        gl.BindTexture(GL_TEXTURE_2D, gpu.work.colour[0]);
        gl.BindVertexArray(gpu.rectVao);
        gl.DrawArrays(GL_TRIANGLES, d.batchRects[b].first, d.batchRects[b].second);
        gl.BindTexture(GL_TEXTURE_2D, 0);
        if (b + 1 < d.batchRange.size()) {
            gl.BindFramebuffer(GL_FRAMEBUFFER, gpu.work.fbo);
            gl.Disable(GL_BLEND);
            gl.UseProgram(gpu.clear);
            gl.DrawArrays(GL_TRIANGLES, d.batchRects[b].first, d.batchRects[b].second);
        }
    }
}

// 2. Receivers: R_max = max over receiver triangles of their farthest depth.
void GpuConfirmStage::LightRun::drawReceivers(const ViewDraw& d) {
    gl.Enable(GL_BLEND);
    gl.BindFramebuffer(GL_FRAMEBUFFER, gpu.recv.fbo);
    const float nothing[4] = {-kBig, 0, 0, 0};
    gl.ClearBufferfv(GL_COLOR, 0, nothing);
    gl.BlendEquation(GL_MAX);
    gl.UseProgram(gpu.raster[Gl::kReceivers]);
    gl.BindVertexArray(gpu.vao);
    drawPieces(d.recvFirst, d.castFirst - d.recvFirst);
}

// 3. Casters: count lit fragments and those with a receiver behind, and record the
// pixels that passed (see Slot), drawing the casters that passed again until the
// records settle.
void GpuConfirmStage::LightRun::drawCasters(const ViewDraw& d) {
    const size_t Q = slots.size();
    for (size_t q = 0; q < Q; ++q)
        slots[q] = {recordsWritten[q] < cap ? kAllPixels : 0u, recordsWritten[q], cap - recordsWritten[q], 0};
    uploadSlots();
    gl.Disable(GL_BLEND);
    gl.BlendEquation(GL_FUNC_ADD);
    gl.BindFramebuffer(GL_FRAMEBUFFER, gpu.work.fbo);
    gl.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    gl.UseProgram(gpu.raster[Gl::kCount]);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindTexture(GL_TEXTURE_2D, gpu.occ.colour[0]);
    gl.ActiveTexture(GL_TEXTURE1);
    gl.BindTexture(GL_TEXTURE_2D, gpu.recv.colour[0]);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, gpu.ssbo[0]);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, gpu.ssbo[1]);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, gpu.ssbo[2]);
    {
        const std::vector<uint32_t> zeros(size_t(d.end - d.castFirst), 0u);
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gpu.ssbo[3]);
        gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(std::max<size_t>(1, zeros.size()) * 4),
                      zeros.empty() ? nullptr : zeros.data(), GL_DYNAMIC_COPY);
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    }
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, gpu.ssbo[3]);
    drawPieces(d.castFirst, d.end - d.castFirst);
    gl.UseProgram(gpu.raster[Gl::kRecord]);  // again if needed: records only, the counts are complete
    GLsizei again = -1;      // caster pieces that passed, copied after the view's pieces
    while (settleSlots()) {
        if (again < 0) {
            // Only a piece with a fragment that passed can record one: the same
            // fragments, the same tests (mode 3 reads what mode 2 read).
            std::vector<uint32_t> passed(size_t(d.end - d.castFirst));
            gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gpu.ssbo[3]);
            gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(passed.size() * 4), passed.data());
            gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
            std::vector<RasterPiece> redraw;
            for (size_t i = 0; i < passed.size(); ++i)
                if (passed[i]) redraw.push_back(gpu.all[size_t(d.castFirst) + i]);
            gl.BindBuffer(GL_ARRAY_BUFFER, gpu.vbo);
            gl.BufferSubData(GL_ARRAY_BUFFER, GLintptr(size_t(d.end) * sizeof(RasterPiece)),
                             GLsizeiptr(redraw.size() * sizeof(RasterPiece)), redraw.data());
            again = GLsizei(redraw.size());
        }
        uploadSlots();
        drawPieces(d.end, again);
        ++stats.gpuPasses;
    }
}

// Back to the default state; with collectViewStats, the view's coverage.
Status GpuConfirmStage::LightRun::finishView(size_t vi, const ViewDraw& d) {
    gl.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    gl.Disable(GL_SCISSOR_TEST);
    gl.MemoryBarrier(GL_ALL_BARRIER_BITS);
    gl.ActiveTexture(GL_TEXTURE1);
    gl.BindTexture(GL_TEXTURE_2D, 0);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindTexture(GL_TEXTURE_2D, 0);
    gl.BindVertexArray(0);
    gl.UseProgram(0);
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    if (Status s = gl.check("the confirmation passes"); !s) return s;
    stats.gpuPasses += size_t(d.batches) + 2;  // occluder batches (each drawn and resolved), receivers, casters
    if (stage.options_.collectViewStats) {
        ConfirmViewStats vs;
        vs.light = l;
        vs.view = int(vi);
        vs.occluderSheets = d.sheets;
        vs.batches = d.batches;
        for (float v : readFloatPixels(gl, gpu.occ, 0, 1, 0)) vs.occluderPixels += v < 1e29f;
        for (float v : readFloatPixels(gl, gpu.recv, 0, 1, 0)) vs.receiverPixels += v > -1e29f;
        stage.viewStats_.push_back(vs);
    }
    return Status::ok();
}

// Read the counts and the pixels that passed; cull the bits no fragment passed for.
Status GpuConfirmStage::LightRun::readResults() {
    const size_t Q = queries.size();
    std::vector<uint32_t> counts(2 * Q);
    std::vector<uint32_t> records(Q * cap * 4);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gpu.ssbo[0]);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(counts.size() * 4), counts.data());
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gpu.ssbo[1]);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(records.size() * 4), records.data());
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    if (Status s = gl.check("reading the confirmation results"); !s) return s;

    const std::string at = std::to_string(res) + " px" + (views.size() > 1 ? " per view, " + std::to_string(views.size()) + " views" : "") +
                           (stage.closeUp_ ? " framed on the casters" : "");
    for (size_t q = 0; q < Q; ++q) {
        GroupPixels& gp = queries[q];
        gp.litSamples = counts[2 * q];
        gp.passedSamples = counts[2 * q + 1];
        passedPixels(gp, q, records);
        decideBit(gp, at);
        stage.groups_.push_back(std::move(gp));
    }
    return Status::ok();
}

// Query q's records, one per pixel at its nearest depth, as rays for the raycast stage.
void GpuConfirmStage::LightRun::passedPixels(GroupPixels& gp, size_t q, const std::vector<uint32_t>& records) const {
    const uint32_t n = recordsWritten[q];
    std::map<std::tuple<int, int, int>, float> nearest;  // (view, px, py) -> nearest depth
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t* r = &records[(q * cap + k) * 4];
        float z;
        std::memcpy(&z, &r[2], 4);
        auto key = std::make_tuple(int(r[3]), int(r[0]), int(r[1]));
        auto it = nearest.find(key);
        if (it == nearest.end() || z < it->second) nearest[key] = z;
    }
    for (const auto& [key, z] : nearest) {
        const auto [v, px, py] = key;
        if (v < 0 || size_t(v) >= views.size()) continue;
        const LightView& view = views[size_t(v)];
        PassedPixel p;
        p.view = v, p.px = px, p.py = py;
        const double cx = px + 0.5, cy = py + 0.5, depth = std::max(double(z), view.perspective ? nearZ : -1e300);
        p.lsPoint = view.pointAt(cx, cy, depth);
        p.lsDirection = view.rayDirection(cx, cy);
        p.footprint = view.pixelSize(depth);
        gp.pixels.push_back(p);
    }
}

// No sample passed: culled, with the reason. Else left undecided, with a note of what
// passed and where (the raycast stage then searches there).
void GpuConfirmStage::LightRun::decideBit(GroupPixels& gp, const std::string& at) {
    if (gp.passedSamples == 0) {
        Decision& d = cv.at(gp.object, gp.group, l);
        if (gp.litSamples == 0)
            decide(d, Verdict::Culled, stage.name(),
                   "never lit: wherever the group is, an opaque sheet covering the whole pixel lies nearer the "
                   "light (conservative rasterisation, " + at + ")");
        else
            decide(d, Verdict::Culled, stage.name(),
                   "nothing behind: no receiver deeper than the bias behind any pixel where the group may be lit "
                   "(conservative rasterisation, " + at + ")");
    }
    if (gp.passedSamples > 0) {
        std::string seen = std::to_string(gp.passedSamples) + " of " + std::to_string(gp.litSamples) +
                           " samples where the group may be lit had a receiver possibly more than the bias behind (" +
                           at + ")";
        if (!gp.pixels.empty()) {
            const PassedPixel& p = gp.pixels.front();
            const glm::dvec3 ws = p.lsPoint + w.wsOrigin;
            seen += "; e.g. view " + std::to_string(p.view) + " pixel (" + std::to_string(p.px) + ", " +
                    std::to_string(p.py) + "): the light's ray through (" + formatNumber(ws.x) + " " + formatNumber(ws.y) +
                    " " + formatNumber(ws.z) + ") along (" + formatNumber(p.lsDirection.x) + " " +
                    formatNumber(p.lsDirection.y) + " " + formatNumber(p.lsDirection.z) + "), " +
                    std::to_string(gp.pixels.size()) + " such pixels kept";
        }
        addNote(cv.at(gp.object, gp.group, l), stage.name(), std::move(seen));
    }
}

}  // namespace shadowcull::gpu
