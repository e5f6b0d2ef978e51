// Witness rays (semantics.md, "The stages": raycast/). For each undecided (group, light),
// rays from the light through sample points on the group. A closest-hit ray, for which
// alpha-tested groups other than the group itself and objects that cast no shadow are
// transparent, finds p; closest-hit
// rays along the same line from beyond depth(p) + bias then walk the surfaces behind p,
// nearest first, until one is a valid q. The line is a witness when
//   1. the first opaque hit is on the group (p lit; alpha-tested groups and objects that
//      cast no shadow are not opaque, the group's own triangles are p itself), with p
//      within range and cone;
//   2. a later hit q lies deeper than depth(p) + bias + slopeBias * tan(theta);
//   3. q's surface faces the light or is two-sided, q is not under terrain by more than
//      terrainTolerance, and q is within range and cone.
// Every comparison of 2 and 3 carries a margin on the side of "no witness", so rounding
// there can only turn a witness into an undecided bit, never create one (condition 1 is
// Embree's float hit alone: an occluder grazing the segment to p within float rounding may
// be missed, a false keep; docs/semantics.md): depths are recomputed in double
// on the hit triangles (Tracer::depthOf) and compared with double rounding's margin, so
// that witnesses a fraction of a millimetre deep count; where that is ill-conditioned,
// Embree's float depths with a margin of 1e-6 of the window's size over the cosine between
// the line and the hit triangle's normal (hit_depth.h).
// Before that test, targets go 16 at a time through an occlusion packet on the window's
// opaque-only scene, each ray ending short of the object's bounds: a target whose line is
// blocked there cannot have p on the group, so it is skipped (a pre-filter; it removes
// no witness the closest-hit test would find, up to rounding on the "no witness" side).
// A clear segment also starts the ray that finds p where it ended: nothing opaque lies
// before, and what is not opaque the closest-hit ray skips anyway (an occluder within
// float rounding of that cut, 2 eps before the object's bounds, may then be missed: at
// most a false keep, as for condition 1 itself). About half the cost of that ray on S.
// Packet tracing: I. Wald, C. Benthin, M. Wagner, P. Slusallek, "Interactive Rendering
// with Coherent Ray Tracing", Computer Graphics Forum 20(3), 2001.
// Embree: I. Wald et al., "Embree: A Kernel Framework for Efficient CPU Ray Tracing",
// ACM TOG 33(4), 2014.

#include "raycast/raycast_stage.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>

#include <embree3/rtcore.h>
#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include "core/line_crossing.h"
#include "raycast/embree_scene.h"
#include "raycast/group_samples.h"
#include "raycast/hit_depth.h"
#include "raycast/receiver_targets.h"
#include "util/float_mode.h"
#include "util/stop_request.h"

namespace shadowcull::raycast {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Hit {
    float t;
    uint32_t object;  // index into BakeWindow::objects
    uint32_t prim;    // triangle index in the object's mesh
};

}  // namespace

struct RaycastStage::Impl {
    RaycastOptions opt;
    RTCDevice device = nullptr;
    std::unique_ptr<EmbreeScenes> scenes;  // prototypes kept for the whole bake
    std::unique_ptr<GroupSampleCache> samples;  // per mesh, for the whole bake
    const BakeWindow* keptFor = nullptr;  // keepScene's window
    std::optional<WindowScene> kept;      // its scene, once a search built it
    size_t shortTargets = 0;              // deferLongSearches
    const BakeWindow* deferredFor = nullptr;  // run()'s window, while `deferred` waits
    std::vector<WitnessSearch> deferred;      // the rest of its short searches
    std::mutex errorMutex;
    std::string lastError;

    ~Impl() {
        kept.reset();
        scenes.reset();  // before the device they belong to
        if (device) rtcReleaseDevice(device);
    }

    static void onError(void* user, RTCError code, const char* message) {
        auto* self = static_cast<Impl*>(user);
        std::lock_guard<std::mutex> lock(self->errorMutex);
        self->lastError = "Embree error " + std::to_string(int(code)) + ": " + (message ? message : "");
    }

    Status takeError() {
        std::lock_guard<std::mutex> lock(errorMutex);
        if (lastError.empty()) return Status::ok();
        Error e = makeError(ErrorKind::Internal, "", 0, lastError);
        lastError.clear();
        return e;
    }
};

RaycastStage::RaycastStage(RaycastOptions options) : impl_(std::make_unique<Impl>()) {
    impl_->opt = options;
    impl_->samples = std::make_unique<GroupSampleCache>(options.areaSamples, options.maxFeatureSamples);
    std::string config = options.threads > 0 ? "threads=" + std::to_string(options.threads) : "";
    impl_->device = rtcNewDevice(config.c_str());
    if (impl_->device) {
        rtcSetDeviceErrorFunction(impl_->device, &Impl::onError, impl_.get());
        impl_->scenes = std::make_unique<EmbreeScenes>(impl_->device);
    }
}

RaycastStage::~RaycastStage() = default;

void RaycastStage::keepScene(const BakeWindow& window) {
    dropScene();
    impl_->keptFor = &window;
}

void RaycastStage::dropScene() {
    impl_->kept.reset();
    impl_->keptFor = nullptr;
    impl_->deferred.clear();
    impl_->deferredFor = nullptr;
}

void RaycastStage::deferLongSearches(size_t firstTargets) { impl_->shortTargets = firstTargets; }

void RaycastStage::forgetMeshes(const std::unordered_set<const Mesh*>& meshes) {
    dropScene();  // it places them
    if (impl_->scenes) impl_->scenes->forget(meshes);
    if (impl_->samples) impl_->samples->forget(meshes);
}

namespace {

// Everything one witness search needs about the window, in window-local double.
struct Tracer {
    const BakeWindow& w;
    const WindowScene& scenes;
    RTCScene scene;   // every triangle
    RTCScene opaque;  // the triangles that block light (WindowScene::opaque)
    const RaycastOptions& opt;
    double eps;        // metres: margin on depth, range and terrain comparisons made on
                       // Embree's float distances
    double exactEps;   // metres: the margin on depths recomputed in double (depthOf)
    double backDist;   // directional lights: ray origins this far before the sample

    // The front normal of `o`'s placed triangle `tri` (WindowObject::lsTriangle).
    static glm::dvec3 frontNormal(const WindowObject& o, const std::array<glm::dvec3, 3>& tri) {
        glm::dvec3 n = glm::cross(tri[1] - tri[0], tri[2] - tri[0]);
        return o.flipsWinding ? -n : n;
    }

    // A hit's distance along the line (origin, unit dir) and the margin a comparison of it
    // needs (hit_depth.h). `tri`: the hit triangle placed in the window (WindowObject::lsTriangle).
    using Depth = HitDepth;
    Depth depthOf(const glm::dvec3& origin, const glm::dvec3& dir, const Hit& h, const std::array<glm::dvec3, 3>& tri) const {
        return hitDepth(origin, dir, h.t, tri, eps, exactEps);
    }

    const PrimitiveGroup& groupOf(const Hit& h) const {
        const WindowObject& o = w.objects[h.object];
        return o.mesh->groups[o.mesh->triangleGroup[h.prim]];
    }

    // `alongLine`: how far x may lie from the true point along its line from the light (a
    // depth's margin; the cone's angle does not change along that line).
    bool withinReach(const Light& L, const glm::dvec3& x, double alongLine = 0.0) const {
        if (L.type == LightType::Directional) return true;
        const glm::dvec3 v = x - L.position;
        const double d = glm::length(v);
        if (!(d <= L.range - std::max(eps, alongLine))) return false;
        if (L.type == LightType::Spot) {
            if (!(d > eps)) return false;
            const double angle = std::acos(std::clamp(glm::dot(v / d, L.direction), -1.0, 1.0));
            if (!(angle <= L.coneHalfAngleDeg * kPi / 180.0 - 1e-6)) return false;
        }
        return true;
    }

    // The closest hit in `in` (a hit in `opaque` named by its mesh triangle).
    std::optional<Hit> closestHit(RTCIntersectContext* ctx, const glm::dvec3& origin, const glm::dvec3& dir, float tnear,
                                  float tfar, RTCScene in) const {
        RTCRayHit rh{};
        rh.ray.org_x = float(origin.x);
        rh.ray.org_y = float(origin.y);
        rh.ray.org_z = float(origin.z);
        rh.ray.dir_x = float(dir.x);
        rh.ray.dir_y = float(dir.y);
        rh.ray.dir_z = float(dir.z);
        rh.ray.tnear = tnear;
        rh.ray.tfar = tfar;
        rh.ray.mask = 0xffffffffu;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(in, ctx, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
        const uint32_t object = hitObject(rh.hit.instID[0], rh.hit.geomID);
        return Hit{rh.ray.tfar, object, in == scene ? rh.hit.primID : scenes.meshTriangle(object, rh.hit.primID)};
    }

    // p: the first hit on a surface that blocks light, or on (object, group) itself, from
    // tnear on. A group that blocks light is itself in the opaque scene, which holds
    // exactly the other surfaces that count: traced there, without a filter function
    // (the same triangles, the same robust floats; only a tie at the very same distance
    // may go to another of the tied triangles, its tree being another). Else in every
    // triangle, the rest skipped (skipTransparent: alpha-tested groups other than this
    // one, and objects that cast no shadow, let light pass).
    std::optional<Hit> firstBlockingHit(uint32_t object, uint32_t group, const glm::dvec3& origin, const glm::dvec3& dir,
                                        float tnear, float tfar) const {
        if (w.objects[object].blocksLight(group) || !needsTransparencyFilter(w)) {
            RTCIntersectContext plain;
            rtcInitIntersectContext(&plain);
            return closestHit(&plain, origin, dir, tnear, tfar, opaque);
        }
        TransparentSkip skip;
        rtcInitIntersectContext(&skip.ctx);
        skip.ctx.filter = &skipTransparent;
        skip.window = &w;
        skip.object = object;
        skip.group = group;
        return closestHit(&skip.ctx, origin, dir, tnear, tfar, scene);
    }

    // The line from the light through `target`: origin, unit direction, the distance to
    // the target and the ray's far end. False when the target is (almost) at the light.
    bool line(const Light& L, const glm::dvec3& target, glm::dvec3& origin, glm::dvec3& dir, double& tTarget,
              double& tfar) const {
        if (L.type == LightType::Directional) {
            dir = L.direction;
            origin = target - dir * backDist;
            tTarget = backDist;
            tfar = 2 * backDist;
            return true;
        }
        origin = L.position;
        const glm::dvec3 v = target - origin;
        tTarget = glm::length(v);
        if (!(tTarget > eps)) return false;
        dir = v / tTarget;
        tfar = L.range;
        return true;
    }

    // Which of `count` (<= 16) targets on `object` may be p: false when an opaque surface
    // blocks the line before it reaches the object's bounds (by more than 2 eps), so that
    // the first opaque hit cannot be on the object. A pre-filter only: a target that passes
    // is decided by tryRay's closest hits alone. One rtcOccluded16 packet on the window's
    // opaque scene (alpha-tested triangles and objects that cast no shadow left out: light
    // passes them; the object itself cannot be hit before its bounds, so no filter is
    // needed). The rays of a packet share the light and aim at one group. Counts the packet's rays in `raysCast`.
    // `tClear[k]`: where target k's line is known clear up to (0 when not tested), the
    // distance its closest-hit ray for p may start from.
    void clearSegments(const Light& L, uint32_t object, const glm::dvec3* targets, int count, bool* clear,
                       float* tClear, uint64_t* raysCast) const {
        alignas(64) RTCRay16 packet;
        alignas(64) int valid[16];
        const Aabb& box = w.objects[object].lsBounds;
        for (int k = 0; k < 16; ++k) {
            valid[k] = 0;
            clear[k] = false;
            tClear[k] = 0.0f;
            packet.tnear[k] = 0.0f;
            packet.time[k] = 0.0f;
            packet.mask[k] = 0xffffffffu;
            packet.id[k] = unsigned(k);
            packet.flags[k] = 0;
            if (k >= count) continue;
            glm::dvec3 origin, dir;
            double tTarget, tfar;
            if (!line(L, targets[k], origin, dir, tTarget, tfar)) continue;
            clear[k] = true;
            const double tSegment = std::min(tTarget, rayBoxEntry(box, origin, dir)) - 2 * eps;
            if (!(tSegment > 0)) continue;  // nothing to test: the line starts at the object
            valid[k] = -1;
            packet.org_x[k] = float(origin.x);
            packet.org_y[k] = float(origin.y);
            packet.org_z[k] = float(origin.z);
            packet.dir_x[k] = float(dir.x);
            packet.dir_y[k] = float(dir.y);
            packet.dir_z[k] = float(dir.z);
            packet.tfar[k] = float(tSegment);
            tClear[k] = packet.tfar[k];
            ++*raysCast;
        }
        // Inactive lanes copy an active one, so that every lane holds a valid ray (Embree's
        // packet kernels compute on all 16 and only mask the results).
        int first = 0;
        while (first < 16 && !valid[first]) ++first;
        if (first == 16) return;
        for (int k = 0; k < 16; ++k) {
            if (valid[k]) continue;
            packet.org_x[k] = packet.org_x[first];
            packet.org_y[k] = packet.org_y[first];
            packet.org_z[k] = packet.org_z[first];
            packet.dir_x[k] = packet.dir_x[first];
            packet.dir_y[k] = packet.dir_y[first];
            packet.dir_z[k] = packet.dir_z[first];
            packet.tfar[k] = packet.tfar[first];
        }
        // Incoherent mode (the default): with RTC_INTERSECT_CONTEXT_FLAG_COHERENT,
        // Embree 3.13.5 never returned from one packet of the two-floating-cubes scene
        // (tests/bake_test.cpp, KnownAnswers.FloatingCubes...).
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        rtcOccluded16(valid, opaque, &ctx, &packet);
        for (int k = 0; k < count; ++k)
            if (valid[k] && packet.tfar[k] < 0) clear[k] = false;  // Embree sets tfar to -inf on a hit
    }

    // A receiver point q and where the line looks its shadow up: the depth t of its lookup
    // point q' on the line (semantics.md condition 5: q' = q + normalBias * n) and the margin
    // a comparison of t needs.
    struct Lookup {
        glm::dvec3 q;
        Depth depth;
    };

    // The lookups hit `h` on triangle `tri` gives the line (origin, unit dir). Without a
    // normal bias, the hit itself (q' = q). With one, the line's crossings of the triangle
    // moved by normalBias along its unit front normal, and against it for a two-sided group
    // (engines differ in which normal they take), each with its q = q' - offset: a crossing
    // within a relative 1e-9 of the moved triangle's edges, or of a moved plane within 1e-3
    // of edge-on, is left out (rounding could put q off the triangle). Returns how many.
    int lookupsOf(const Light& L, const glm::dvec3& origin, const glm::dvec3& dir, const Hit& h,
                  const std::array<glm::dvec3, 3>& tri, Lookup out[2]) const {
        if (!(L.normalBias > 0)) {
            const Depth d = depthOf(origin, dir, h, tri);
            out[0] = {origin + dir * d.t, d};
            return 1;
        }
        const WindowObject& ro = w.objects[h.object];
        const glm::dvec3 n = frontNormal(ro, tri);
        const double nl = glm::length(n);
        if (!(nl > 0)) return 0;
        const bool twoSided = ro.mesh->groups[ro.mesh->triangleGroup[h.prim]].twoSided();
        int count = 0;
        for (double sign : {1.0, -1.0}) {
            if (sign < 0 && !twoSided) break;
            const glm::dvec3 offset = (sign * L.normalBias / nl) * n;
            const LineCrossing x = lineCrossing(origin, dir, tri[0] + offset, tri[1] - tri[0], tri[2] - tri[0]);
            if (!(std::abs(x.det) > 1e-3 * nl)) continue;
            constexpr double kInside = 1e-9;
            if (!(x.u > kInside && x.v > kInside && x.u + x.v < 1 - kInside)) continue;
            out[count++] = {origin + dir * x.t - offset, Depth{x.t, exactEps}};
        }
        return count;
    }

    // Whether the lookup is a valid q for p at depth tp (margin pMargin): semantics.md
    // conditions 2, 3 and 5, each with a margin on the side of "no witness".
    bool receivesBehind(const Light& L, const WindowObject& ro, const Hit& h, const std::array<glm::dvec3, 3>& tri,
                        const Lookup& lk, double tp, double pMargin, const glm::dvec3& dir) const {
        const double margin = std::max(pMargin, lk.depth.margin);
        const double gap = lk.depth.t - tp;
        if (!(gap > L.bias + margin)) return false;
        const PrimitiveGroup& rg = ro.mesh->groups[ro.mesh->triangleGroup[h.prim]];
        glm::dvec3 n = frontNormal(ro, tri);
        const double nl = glm::length(n);
        if (!(nl > 0)) return false;
        // The way light travels at q (the line's own direction unless a normal bias moved q
        // off it towards a point light).
        const glm::dvec3 towardsQ =
            L.normalBias > 0 && L.type != LightType::Directional ? glm::normalize(lk.q - L.position) : dir;
        const double cosFacing = glm::dot(n / nl, towardsQ);  // < 0: the light meets the front
        if (!rg.twoSided() && !(cosFacing < -1e-6)) return false;
        const double c = std::abs(cosFacing);
        if (L.slopeBias > 0) {
            if (!(c > 1e-6)) return false;
            const double tanTheta = std::sqrt(std::max(0.0, 1 - c * c)) / c;
            if (!(gap > L.bias + L.slopeBias * tanTheta + margin)) return false;
        }
        if (!withinReach(L, lk.q, lk.depth.margin)) return false;
        if (w.hasTerrain && ro.kind != ChunkObject::Kind::Terrain) {
            std::optional<double> ground = w.lsTerrainHeight(lk.q.x, lk.q.z);
            if (ground && !(lk.q.y >= *ground - w.terrainTolerance + lk.depth.margin)) return false;
        }
        return true;
    }

    // Traces towards `target` on (object, group); returns a witness or nothing. Counts the
    // Embree calls in `raysCast`. `tClear`: the line holds nothing opaque before it
    // (clearSegments), so the search for p starts there.
    std::optional<Witness> tryRay(const Light& L, uint32_t object, uint32_t group, const glm::dvec3& target, float tClear,
                                  const std::optional<std::array<uint32_t, 2>>& receiverHint, uint64_t* raysCast) const {
        glm::dvec3 origin, dir;
        double tTarget, tfar;
        if (!line(L, target, origin, dir, tTarget, tfar)) return std::nullopt;
        std::optional<Hit> first = firstBlockingHit(object, group, origin, dir, tClear, float(tfar));
        ++*raysCast;
        if (!first || first->object != object || w.objects[object].mesh->triangleGroup[first->prim] != group)
            return std::nullopt;
        const Depth dp = depthOf(origin, dir, *first, w.objects[first->object].lsTriangle(first->prim));
        const double tp = dp.t;
        const glm::dvec3 p = origin + dir * tp;
        if (!withinReach(L, p, dp.margin)) return std::nullopt;
        auto witness = [&](const WindowObject& ro, const Hit& h, const Lookup& lk) {
            Witness wit;
            wit.wsOrigin = origin + w.wsOrigin;
            wit.wsDirection = dir;
            wit.wsP = p + w.wsOrigin;
            wit.wsQ = lk.q + w.wsOrigin;
            wit.receiver = ro.label + " group " + std::to_string(ro.mesh->triangleGroup[h.prim]);
            wit.wsReceiverMin = ro.lsBounds.min + w.wsOrigin;
            wit.wsReceiverMax = ro.lsBounds.max + w.wsOrigin;
            return wit;
        };
        if (receiverHint && L.normalBias > 0) {
            // The receiver the line was aimed at, by its moved copy (the line may miss it).
            const Hit h{0.0f, (*receiverHint)[0], (*receiverHint)[1]};
            const WindowObject& ro = w.objects[h.object];
            const std::array<glm::dvec3, 3> tri = ro.lsTriangle(h.prim);
            Lookup lookups[2];
            const int count = hasRepeatedVertex(*ro.mesh, h.prim) ? 0 : lookupsOf(L, origin, dir, h, tri, lookups);
            for (int i = 0; i < count; ++i)
                if (receivesBehind(L, ro, h, tri, lookups[i], tp, dp.margin, dir)) return witness(ro, h, lookups[i]);
        }

        // q: the receivers behind p along the same line, nearest first, from where Embree
        // may place one more than the bias behind (its distances are within eps); never
        // before the ray's origin (a p within eps of a point light, bias 0: Embree requires
        // tnear >= 0). With a normal bias the line's point is the lookup q' of a receiver
        // point q beside it (lookupsOf), which may lie before its own surface's hit: from p on.
        RTCIntersectContext plain;
        rtcInitIntersectContext(&plain);
        float tnear = float(std::max(0.0, L.normalBias > 0 ? tp - eps : tp + L.bias - eps));
        for (int k = 0; k < opt.maxHitsPerRay; ++k) {
            std::optional<Hit> next = closestHit(&plain, origin, dir, tnear, float(tfar), scene);
            ++*raysCast;
            if (!next) return std::nullopt;
            const Hit& h = *next;
            // Skip past this surface (and any coincident with it) for the next step.
            tnear = float(double(h.t) + 0.5 * eps);
            const WindowObject& ro = w.objects[h.object];
            const std::array<glm::dvec3, 3> tri = ro.lsTriangle(h.prim);
            Lookup lookups[2];
            const int count = lookupsOf(L, origin, dir, h, tri, lookups);
            for (int i = 0; i < count; ++i)
                if (receivesBehind(L, ro, h, tri, lookups[i], tp, dp.margin, dir)) return witness(ro, h, lookups[i]);
        }
        return std::nullopt;
    }
};

// The tracer of a window's scene, with margins well above float rounding of window-local
// coordinates (~6e-8 relative) for Embree's positions (eps: how far its hit point may lie
// off the hit triangle's plane; a distance along the line gets eps over the cosine,
// hit_depth.h), and 1e-9 of the same scale for depths recomputed in double (far above
// double rounding). Point and spot lights widen both by their position and range.
Tracer makeTracer(const BakeWindow& window, const WindowScene& scene, const RaycastOptions& opt) {
    const glm::dvec3 ext = glm::max(glm::abs(window.lsBounds.min), glm::abs(window.lsBounds.max));
    const double diag = glm::length(window.lsBounds.max - window.lsBounds.min);
    const double scale = std::max({ext.x, ext.y, ext.z}) + diag;
    Tracer tracer{window, scene, scene.all(), scene.opaque(), opt, 1e-6 * scale + 1e-6, 1e-9 * scale + 1e-12, diag + 1.0};
    for (const Light& L : window.lsLights)
        if (L.type != LightType::Directional) {
            tracer.eps = std::max(tracer.eps, 1e-6 * (glm::length(L.position) + L.range) + 1e-6);
            tracer.exactEps = std::max(tracer.exactEps, 1e-9 * (glm::length(L.position) + L.range) + 1e-12);
        }
    return tracer;
}

// One pass of witness searches over a window: every search's targets, each light it asks
// for that is still undecided; in parallel over the searches (TBB).
struct SearchPass {
    const Tracer& tracer;
    const BakeWindow& window;
    ChunkVerdicts& cv;
    const RaycastOptions& opt;
    GroupSampleCache& samples;
    std::atomic<uint64_t>& rays;
    std::atomic<uint64_t>& kept;
    std::atomic<uint64_t>& examined;
    // Non-null: a bit of a large caster that the group's own samples leave undecided gets
    // the receiver-side search (receiver_targets.h) right after them, in the same task, with
    // this reason; so the few long searches of a window's terrains share the threads with
    // its other searches instead of running after them, two or three at a time.
    const char* receiverSideWhy = nullptr;
    // Non-zero: a terrain's own-sample searches trace only their first `shortTargets`
    // samples; each bit left undecided goes to `deferred` (under its mutex) with what a
    // later search needs to go on (RaycastStage::deferLongSearches), and so does every
    // other large caster's receiver-side search.
    size_t shortTargets = 0;
    std::mutex* deferredMutex = nullptr;
    std::vector<WitnessSearch>* deferred = nullptr;

    bool defers(const WindowObject& o) const { return shortTargets > 0 && o.kind == ChunkObject::Kind::Terrain; }

    // `countExamined`: the bits count once per stage run (the receiver-side pass examines
    // bits the first one already counted).
    void run(std::vector<WitnessSearch>& tasks, const char* why, bool countExamined) const {
        tbb::parallel_for(size_t(0), tasks.size(), [&](size_t ti) {
            // A signal: the searches not begun stay undecided; the stage then stops.
            if (stopRequested()) return;
            // Denormals in traversal cost ~100x per operation; the geometry never needs them.
            const FloatModeScope ftz(FloatModeScope::Underflow::FlushToZero);
            searchTask(tasks[ti], why, countExamined);
        });
    }

    void searchTask(WitnessSearch& task, const char* why, bool countExamined) const {
        const ObjectVerdicts& ov = cv.objects[task.object];
        const uint32_t object = uint32_t(ov.windowObject);
        // The group's own samples (mesh coordinates), placed as the searches reach them.
        const std::vector<glm::dvec3>* msOwn =
            task.targets.empty() && !task.throughReceivers ? &samples.meshPoints(*window.objects[object].mesh, uint32_t(task.group))
                                                           : nullptr;
        const bool ownSamples = msOwn != nullptr;
        // A receiver-side search left for later (deferLongSearches) keeps its reason, and
        // costs nothing once a stage in between decided its bit.
        if (task.throughReceivers) {
            if (receiverSideWhy) why = receiverSideWhy;
            if (task.light >= 0 && cv.at(task.object, task.group, task.light).verdict != Verdict::Undecided) return;
        }
        if (task.targets.empty() && task.throughReceivers && task.light >= 0)
            task.targets = receiverTargets(window, object, uint32_t(task.group), window.lsLights[size_t(task.light)],
                                           opt.receiverSamples, samples);
        uint64_t localRays = 0;
        std::optional<bool> large;  // isLargeCaster, asked once
        std::vector<WitnessSearch> through;  // the receiver-side searches the bits call for
        const bool shortFirst = ownSamples && defers(window.objects[object]);
        for (int l = 0; l < cv.lightCount; ++l) {
            if (task.light >= 0 && l != task.light) continue;
            Decision& d = cv.at(task.object, task.group, l);
            if (d.verdict != Verdict::Undecided) continue;
            if (countExamined) ++examined;
            if (shortFirst) {
                searchShort(task, object, *msOwn, l, d, why, localRays);
                continue;
            }
            searchBit(task, object, window.lsLights[size_t(l)], msOwn, d, why, localRays);
            if (!receiverSideWhy || !ownSamples || d.verdict != Verdict::Undecided) continue;
            if (!large) large = isLargeCaster(window.objects[object], uint32_t(task.group), opt.areaSamples, opt.largeCasterSpacing);
            if (!*large) continue;
            through.push_back({task.object, task.group, l, {}});
            through.back().throughReceivers = true;
        }
        rays += localRays;
        if (through.empty()) return;
        if (deferred) {
            // After the shadow volumes too, as a terrain's: they prove most such bits 0.
            std::lock_guard<std::mutex> lock(*deferredMutex);
            for (WitnessSearch& t : through) deferred->push_back(std::move(t));
            return;
        }
        // One bit per light, each a task of its own (a terrain's lights in parallel).
        run(through, receiverSideWhy, false);
    }

    // True when a ray through one of `points` is a witness (the bit is then decided); `lit`
    // counts those with a clear segment. Targets in packets of 16: an occlusion packet drops
    // those whose line is blocked before the group (most of them where a bit ends
    // undecided), then closest hits examine the rest in order until one is a witness. A
    // long list (a receiver-side search: thousands of targets, most often all of them
    // traced for nothing) in blocks on every thread, the witness of the first target in
    // order kept: the same witness as one thread going through them in order.
    // Points [begin, end) only.
    bool searchThrough(const WitnessSearch& task, uint32_t object, const Light& L, const std::vector<glm::dvec3>& points,
                       size_t begin, size_t end, Decision& d, const char* why, size_t& lit, uint64_t& localRays) const {
        std::optional<Witness> wit = end - begin >= 2 * kTargetBlock
                                         ? firstWitnessInBlocks(task, object, L, points, begin, end, lit, localRays)
                                         : firstWitness(task, object, L, points, begin, end, nullptr, lit, localRays);
        if (!wit) return false;
        decide(d, Verdict::Kept, "raycast", why, std::move(*wit));
        ++kept;
        return true;
    }

    // Targets per block of a long list: 16 packets.
    static constexpr size_t kTargetBlock = 256;

    // The witness of the first of points [begin, end) in order that has one. With `found`
    // (blocks in parallel): the index of the first target known to have one; the block stops
    // at a packet past it (that packet's witness could not be the first).
    std::optional<Witness> firstWitness(const WitnessSearch& task, uint32_t object, const Light& L,
                                        const std::vector<glm::dvec3>& points, size_t begin, size_t end,
                                        std::atomic<size_t>* found, size_t& lit, uint64_t& localRays) const {
        for (size_t b = begin; b < end; b += 16) {
            if (found && found->load(std::memory_order_relaxed) < b) return std::nullopt;
            const int count = int(std::min<size_t>(16, end - b));
            bool clear[16];
            float tClear[16];
            tracer.clearSegments(L, object, &points[b], count, clear, tClear, &localRays);
            for (int k = 0; k < count; ++k) {
                if (!clear[k]) continue;
                ++lit;
                if (std::optional<Witness> wit =
                        tracer.tryRay(L, object, uint32_t(task.group), points[b + size_t(k)], tClear[k], task.receiver, &localRays)) {
                    if (found) {
                        size_t first = found->load();
                        while (b + size_t(k) < first && !found->compare_exchange_weak(first, b + size_t(k))) {
                        }
                    }
                    return wit;
                }
            }
        }
        return std::nullopt;
    }

    // firstWitness over blocks of kTargetBlock points in parallel (in the calling thread's
    // floating-point mode), joined in order: the first block's witness that has one. `lit`
    // and the rays are those of the blocks up to it, as in order (every block before it was
    // gone through to its end; the block itself stopped at its witness): the same counts on
    // any number of threads, the rays of later blocks not counted.
    std::optional<Witness> firstWitnessInBlocks(const WitnessSearch& task, uint32_t object, const Light& L,
                                                const std::vector<glm::dvec3>& points, size_t pointsBegin,
                                                size_t pointsEnd, size_t& lit, uint64_t& localRays) const {
        const size_t blocks = (pointsEnd - pointsBegin + kTargetBlock - 1) / kTargetBlock;
        struct Block {
            std::optional<Witness> witness;
            size_t lit = 0;
            uint64_t rays = 0;
        };
        std::vector<Block> parts(blocks);
        std::atomic<size_t> found{std::numeric_limits<size_t>::max()};
        const FloatModeScope::Underflow callers = FloatModeScope::current();
        tbb::parallel_for(size_t(0), blocks, [&](size_t i) {
            const FloatModeScope mode(callers);
            Block& part = parts[i];
            const size_t begin = pointsBegin + i * kTargetBlock, end = std::min(pointsEnd, begin + kTargetBlock);
            part.witness = firstWitness(task, object, L, points, begin, end, &found, part.lit, part.rays);
        });
        for (Block& part : parts) {
            lit += part.lit;
            localRays += part.rays;
            if (part.witness) return std::move(part.witness);
        }
        return std::nullopt;
    }

    // Own samples placed before a search goes on past its first packets (placeSamples).
    static constexpr size_t kFirstPlaced = 64;

    // The first `count` of the group's own samples `msOwn` placed in task.targets (all
    // when fewer); how many are.
    size_t placeOwn(WitnessSearch& task, uint32_t object, const std::vector<glm::dvec3>& msOwn, size_t count) const {
        placeSamples(window.objects[object], msOwn, count, task.targets);
        return task.targets.size();
    }

    // One bit: the task's targets (with `msOwn`, the group's own samples: their first
    // packets, then the rest, the same witness and counts as one list), then, for a point
    // or spot light whose reach cuts the group, points on the part within reach (its own
    // points beyond reach cannot be p). Without a witness, a note says what was tried.
    // From the task's fromTarget on, its litBefore counted lit.
    void searchBit(WitnessSearch& task, uint32_t object, const Light& L, const std::vector<glm::dvec3>* msOwn,
                   Decision& d, const char* why, uint64_t& localRays) const {
        const bool ownSamples = msOwn != nullptr;
        const std::vector<glm::dvec3>& targets = task.targets;
        size_t lit = task.litBefore;
        size_t end = ownSamples ? placeOwn(task, object, *msOwn, task.fromTarget + kFirstPlaced) : targets.size();
        const size_t from = std::min(task.fromTarget, end);
        if (searchThrough(task, object, L, targets, from, end, d, why, lit, localRays)) return;
        if (ownSamples && end < msOwn->size()) {
            const size_t placedBefore = end;
            end = placeOwn(task, object, *msOwn, msOwn->size());
            if (searchThrough(task, object, L, targets, placedBefore, end, d, why, lit, localRays)) return;
        }
        std::vector<glm::dvec3> within;
        size_t litWithin = 0;
        if (ownSamples && L.type != LightType::Directional &&
            std::any_of(targets.begin(), targets.end(), [&](const glm::dvec3& t) { return !tracer.withinReach(L, t); })) {
            within = sampleGroupWithinReach(window.objects[object], uint32_t(task.group), L, opt.areaSamples,
                                            opt.maxFeatureSamples);
            if (searchThrough(task, object, L, within, 0, within.size(), d, why, litWithin, localRays)) return;
        }
        if (task.throughReceivers)
            addNote(d, "raycast",
                    "no witness through the receivers in its shadow either: of " + std::to_string(targets.size()) +
                        " points on them, " + std::to_string(lit) +
                        " have a clear segment from the light to the group's bounds, and no ray through them "
                        "has its first opaque hit on the group and a receiver more than the bias behind");
        else if (!ownSamples)
            addNote(d, "raycast",
                    "no witness either through " + std::to_string(targets.size()) +
                        " points where another stage saw a shadow may fall (" + std::to_string(lit) +
                        " with a clear segment from the light to the group's bounds)");
        else
            addNote(d, "raycast",
                    "no witness: of " + std::to_string(targets.size()) + " points on the group, " + std::to_string(lit) +
                        " are lit (the light's segment to them is clear), and no ray through them meets a "
                        "receiver more than the bias behind" +
                        (within.empty() ? std::string()
                                        : "; nor through " + std::to_string(within.size()) +
                                              " points on its triangles within the light's reach (" +
                                              std::to_string(litWithin) + " lit)"));
    }

    // The first shortTargets of a bit's own samples; undecided, it is deferred (no note
    // yet: the rest of the search adds it) with where the rest begins.
    void searchShort(WitnessSearch& task, uint32_t object, const std::vector<glm::dvec3>& msOwn, int light, Decision& d,
                     const char* why, uint64_t& localRays) const {
        const std::vector<glm::dvec3>& targets = task.targets;
        // (The cut is shortTargets whatever the task placed before, as it was before samples
        // were placed lazily; today only searchShort places a short-first task's samples.)
        const size_t end = std::min(shortTargets, placeOwn(task, object, msOwn, shortTargets));
        size_t lit = 0;
        if (searchThrough(task, object, window.lsLights[size_t(light)], targets, 0, end, d, why, lit, localRays)) return;
        WitnessSearch rest{task.object, task.group, light, {}};
        rest.fromTarget = end;
        rest.litBefore = lit;
        std::lock_guard<std::mutex> lock(*deferredMutex);
        deferred->push_back(std::move(rest));
    }
};

}  // namespace

Status RaycastStage::run(const BakeWindow& window, ChunkVerdicts& cv, StageStats& stats) {
    // One search per (centre object, group) with an undecided light: the group's samples,
    // for every such light.
    std::vector<WitnessSearch> searches;
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        for (int g = 0; g < cv.objects[oi].groupCount; ++g)
            for (int l = 0; l < cv.lightCount; ++l)
                if (cv.at(oi, g, l).verdict == Verdict::Undecided) {
                    searches.push_back({oi, g, -1, {}});
                    break;
                }
    return search(window, cv, searches, stats, "witness ray", Pass::Stage);
}

Status RaycastStage::finishDeferred(const BakeWindow& window, ChunkVerdicts& cv, StageStats& stats) {
    Impl& im = *impl_;
    if (im.deferredFor != &window) return Status::ok();
    std::vector<WitnessSearch> rest = std::move(im.deferred);
    im.deferred.clear();
    im.deferredFor = nullptr;
    return search(window, cv, rest, stats, "witness ray", Pass::Deferred);
}

Status RaycastStage::searchAt(const BakeWindow& window, ChunkVerdicts& cv, std::vector<WitnessSearch> searches,
                              StageStats& stats, const char* reason) {
    return search(window, cv, searches, stats, reason, Pass::At);
}

Status RaycastStage::search(const BakeWindow& window, ChunkVerdicts& cv, std::vector<WitnessSearch>& searches,
                            StageStats& stats, const char* reason, Pass which) {
    const auto t0 = std::chrono::steady_clock::now();
    Impl& im = *impl_;
    if (!im.device) return makeError(ErrorKind::Internal, "", 0, "Embree device could not be created");
    if (searches.empty()) return Status::ok();  // nothing undecided: nothing for the receiver side either

    try {
        WindowScene own;  // this search's, unless keepScene's window holds one
        const bool keep = im.keptFor == &window;
        if (keep && !im.kept) im.kept = im.scenes->buildWindow(window);
        if (!keep) own = im.scenes->buildWindow(window);
        if (Status s = im.takeError(); !s) return s;
        const WindowScene& scene = keep ? *im.kept : own;
        const Tracer tracer = makeTracer(window, scene, im.opt);
        std::atomic<uint64_t> rays{0}, kept{0}, examined{0};
        SearchPass pass{tracer, window, cv, im.opt, *im.samples, rays, kept, examined};
        if (which != Pass::At && im.opt.receiverSamples > 0)
            pass.receiverSideWhy = "witness ray through a receiver in the group's shadow (receiver-side search)";
        std::mutex deferredMutex;
        std::vector<WitnessSearch> deferred;
        if (which == Pass::Stage && im.shortTargets > 0) {
            pass.shortTargets = im.shortTargets;
            pass.deferredMutex = &deferredMutex;
            pass.deferred = &deferred;
        }
        pass.run(searches, reason, which != Pass::Deferred);
        if (Status s = stopStatus(); !s) return s;
        if (pass.deferred) {
            // In whatever order the threads left them: each is one bit, searched on its own.
            im.deferred = std::move(deferred);
            im.deferredFor = &window;
        }
        own.reset();
        im.scenes->noteRays(rays);
        stats.raysCast += rays;
        stats.provedKept += kept;
        stats.bitsExamined += examined;
        if (Status s = im.takeError(); !s) return s;
    } catch (const std::exception& e) {
        return makeError(ErrorKind::Internal, "", 0, std::string("raycast stage: ") + e.what());
    }
    stats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Status::ok();
}

}  // namespace shadowcull::raycast
