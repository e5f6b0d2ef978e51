// The bare Embree loop that the pipeline's raycast stage is compared with (issue 6: "rays/s
// at least half of a bare Embree occlusion loop over the same scene").
//
// The scene is the one raycast/raycast_stage.cpp traces, built by the same code
// (raycast/embree_scene.h): one Embree scene per mesh resource and per terrain
// (RTC_SCENE_FLAG_ROBUST | CONTEXT_FILTER_FUNCTION), placed by instances in window-local
// floats; the loops trace its full version (every triangle). The rays are the ones
// the stage would cast in that window: for every primitive group of the centre chunk and
// every light that reaches it, rays from the light through the group's sample points
// (raycast::sampleGroup, 256 area + up to 1024 feature samples); directional rays start
// before the loaded bounds and cross the whole window, like the stage's. The loops cycle
// through that list (each light's share weighted like the stage's examined bits per light)
// until `rays` rays have been traced, after an untimed warm-up, in parallel over TBB:
//
//  - occluded1:  rtcOccluded1, one ray at a time, on the segment light -> sample point
//                (the shadow ray deciding whether p is lit; any hit ends it)
//  - occluded16: rtcOccluded16, packets of 16 consecutive segments (same group and light)
//  - occluded1Full: rtcOccluded1 on the stage's whole ray (JSON only: it always stops on
//                the sample's own surface at the latest, so it measures little)
//  - closest1:   rtcIntersect1 with the stage's alpha-skip context filter (hits on
//                alpha-tested groups other than the ray's target group are rejected): the
//                stage's first ray per sample (finding p), without any witness logic.
//  - allhits1:   rtcIntersect1 with an all-hit context filter (keeps the nearest 48 hits,
//                rejects every hit so traversal visits all of them): the stage's method
//                before commit 7d9003e, kept for comparison.
//
// Called from bake_bench (in a child process); returns its figures as JSON.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include <embree3/rtcore.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "core/scene.h"
#include "core/window.h"
#include "io/scene_reader.h"
#include "raycast/embree_scene.h"
#include "raycast/group_samples.h"
#include "util/float_mode.h"

namespace shadowcull::bench {

namespace {

struct Ray {
    float org[3], dir[3], tfar;
    float tshadow;           // just short of the sample point: the light -> p segment
    uint32_t object, group;  // the group the ray aims at (window object index, group)
};

struct Hit {
    float t;
    uint32_t object, prim;
};

// The stage's hit collector (raycast_stage.cpp), reproduced: keep the nearest `capacity`
// hits sorted, reject every hit so traversal continues.
struct HitCollector {
    RTCIntersectContext ctx;
    Hit* hits = nullptr;
    int capacity = 0;
    int count = 0;
    uint64_t visited = 0;  // every hit the traversal reported (the stage does not count these)
};

bool nearer(const Hit& a, const Hit& b) {
    if (a.t != b.t) return a.t < b.t;
    return a.object != b.object ? a.object < b.object : a.prim < b.prim;
}

void collectAllHits(const RTCFilterFunctionNArguments* args) {
    auto* hc = reinterpret_cast<HitCollector*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (!args->valid[i]) continue;
        args->valid[i] = 0;
        ++hc->visited;
        Hit h;
        h.t = RTCRayN_tfar(args->ray, args->N, i);
        const unsigned inst = RTCHitN_instID(args->hit, args->N, i, 0);
        h.object = inst != RTC_INVALID_GEOMETRY_ID ? inst : RTCHitN_geomID(args->hit, args->N, i);
        h.prim = RTCHitN_primID(args->hit, args->N, i);
        bool dup = false;
        for (int k = 0; k < hc->count && !dup; ++k) dup = hc->hits[k].object == h.object && hc->hits[k].prim == h.prim;
        if (dup) continue;
        if (hc->count == hc->capacity) {
            if (!nearer(h, hc->hits[hc->count - 1])) continue;
            --hc->count;
        }
        int k = hc->count++;
        while (k > 0 && nearer(h, hc->hits[k - 1])) {
            hc->hits[k] = hc->hits[k - 1];
            --k;
        }
        hc->hits[k] = h;
    }
}

double secondsSince(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// The stage's rays: per centre group and reaching light, through its sample points (one
// list per light); `centreGroups` counts the groups with samples.
std::vector<std::vector<Ray>> stageRays(const BakeWindow& w, uint64_t& centreGroups) {
    const double diag = glm::length(w.lsBounds.max - w.lsBounds.min);
    const double backDist = diag + 1.0;
    std::vector<std::vector<Ray>> perLight(w.lsLights.size());
    for (uint32_t oi = 0; oi < w.objects.size(); ++oi) {
        const WindowObject& o = w.objects[oi];
        if (!o.centre || !o.source->castsShadow) continue;
        for (uint32_t g = 0; g < o.mesh->groups.size(); ++g) {
            const std::vector<glm::dvec3> samples = raycast::sampleGroup(o, g, 256, 1024);
            if (samples.empty()) continue;
            ++centreGroups;
            for (size_t l = 0; l < w.lsLights.size(); ++l) {
                const Light& L = w.lsLights[l];
                for (const glm::dvec3& s : samples) {
                    Ray r;
                    glm::dvec3 origin, dir;
                    double tfar, tshadow;
                    if (L.type == LightType::Directional) {
                        dir = L.direction;
                        origin = s - dir * backDist;
                        tfar = 2 * backDist;
                        tshadow = backDist - 1e-3;
                    } else {
                        const glm::dvec3 v = s - L.position;
                        const double d = glm::length(v);
                        if (!(d > 1e-6) || d > L.range) continue;  // the reach stage decides these
                        if (L.type == LightType::Spot &&
                            std::acos(std::clamp(glm::dot(v / d, L.direction), -1.0, 1.0)) > L.coneHalfAngleDeg * 3.14159265358979 / 180)
                            continue;
                        origin = L.position;
                        dir = v / d;
                        tfar = L.range;
                        tshadow = d - 1e-3;
                    }
                    for (int c = 0; c < 3; ++c) {
                        r.org[c] = float(origin[c]);
                        r.dir[c] = float(dir[c]);
                    }
                    r.tfar = float(tfar);
                    r.tshadow = float(tshadow);
                    r.object = oi;
                    r.group = g;
                    perLight[l].push_back(r);
                }
            }
        }
    }
    return perLight;
}

// The mix: each light's share of the list follows `lightWeights` (the bits the stage
// examined per light in the whole bake), so that the loop traces directional and local
// rays in the stage's proportions; within a light, groups and samples in the stage's
// order (consecutive rays share a group and a light, as in the stage). `mix`: rays per
// light; `available`: the rays of every light.
std::vector<Ray> mixedRays(const BakeWindow& w, const std::vector<std::vector<Ray>>& perLight,
                           const std::vector<double>& lightWeights, nlohmann::json& mix, uint64_t& available) {
    std::vector<double> weight(w.lsLights.size(), 1.0);
    if (lightWeights.size() == weight.size()) weight = lightWeights;
    double sum = 0;
    for (size_t l = 0; l < weight.size(); ++l) {
        if (perLight[l].empty()) weight[l] = 0;
        sum += weight[l];
        available += perLight[l].size();
    }
    const uint64_t listSize = std::min<uint64_t>(available, 2000000);
    std::vector<Ray> list;
    mix = nlohmann::json::object();
    for (size_t l = 0; l < weight.size() && sum > 0; ++l) {
        const uint64_t take = uint64_t(std::llround(double(listSize) * weight[l] / sum));
        for (uint64_t k = 0; k < take; ++k) list.push_back(perLight[l][size_t(k % perLight[l].size())]);
        if (take) mix[w.lsLights[l].name] = take;
    }
    return list;
}

RTCRay ray1(const Ray& s, float tfar) {
    RTCRay ray{};
    ray.org_x = s.org[0], ray.org_y = s.org[1], ray.org_z = s.org[2];
    ray.dir_x = s.dir[0], ray.dir_y = s.dir[1], ray.dir_z = s.dir[2];
    ray.tnear = 0.0f;
    ray.tfar = tfar;
    ray.mask = 0xffffffffu;
    return ray;
}

// The loops over rays [b, e) of the list (taken round-robin), each returning its metric's
// count.
struct Loops {
    const BakeWindow& w;
    RTCScene scene;
    const std::vector<Ray>& list;
    const Ray& rayAt(uint64_t i) const { return list[size_t(i % list.size())]; }

    // rtcOccluded1 on the segment light -> sample point (`shadow`: the shadow ray of "is p
    // lit") or on the whole ray (the stage's tfar: always ends on the sample's own surface
    // at the latest, so it is cheap); the count of rays occluded (alpha-tested cards count
    // as opaque here).
    uint64_t occluded1(uint64_t b, uint64_t e, bool shadow) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        uint64_t occluded = 0;
        for (uint64_t i = b; i < e; ++i) {
            RTCRay ray = ray1(rayAt(i), shadow ? rayAt(i).tshadow : rayAt(i).tfar);
            rtcOccluded1(scene, &ctx, &ray);
            occluded += ray.tfar < 0;  // Embree sets tfar to -inf when occluded
        }
        return occluded;
    }
    // rtcOccluded16: packets of 16 consecutive segments (same group and light).
    uint64_t occluded16(uint64_t b, uint64_t e) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        alignas(64) RTCRay16 p;
        alignas(64) int valid[16];
        uint64_t occluded = 0;
        for (uint64_t q0 = b; q0 < e; q0 += 16) {
            for (int k = 0; k < 16; ++k) {
                const uint64_t i = q0 + uint64_t(k);
                valid[k] = i < e ? -1 : 0;
                const Ray& s = rayAt(i);
                p.org_x[k] = s.org[0], p.org_y[k] = s.org[1], p.org_z[k] = s.org[2];
                p.dir_x[k] = s.dir[0], p.dir_y[k] = s.dir[1], p.dir_z[k] = s.dir[2];
                p.tnear[k] = 0.0f;
                p.tfar[k] = s.tshadow;
                p.mask[k] = 0xffffffffu;
                p.time[k] = 0.0f;
                p.id[k] = unsigned(k);
                p.flags[k] = 0;
            }
            rtcOccluded16(valid, scene, &ctx, &p);
            for (int k = 0; k < 16; ++k) occluded += valid[k] && p.tfar[k] < 0;
        }
        return occluded;
    }
    // rtcIntersect1 with the stage's transparency filter over the whole ray (the stage's ray
    // for p); the count whose closest opaque hit is on the target object.
    uint64_t closest1(uint64_t b, uint64_t e) const {
        uint64_t onTarget = 0;
        for (uint64_t i = b; i < e; ++i) {
            const Ray& s = rayAt(i);
            raycast::TransparentSkip skip;
            rtcInitIntersectContext(&skip.ctx);
            if (raycast::needsTransparencyFilter(w)) {
                skip.ctx.filter = &raycast::skipTransparent;
                skip.window = &w;
                skip.object = s.object;
                skip.group = s.group;
            }
            RTCRayHit rh{};
            rh.ray = ray1(s, s.tfar);
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene, &skip.ctx, &rh);
            const unsigned object = rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID ? rh.hit.instID[0] : rh.hit.geomID;
            onTarget += object == s.object;
        }
        return onTarget;
    }
    // rtcIntersect1 with an all-hit filter (the nearest 48 hits kept, every hit rejected so
    // traversal visits all): the stage's method before commit 7d9003e; the hits visited.
    uint64_t allHits1(uint64_t b, uint64_t e) const {
        std::vector<Hit> buffer(48);
        uint64_t visited = 0;
        for (uint64_t i = b; i < e; ++i) {
            const Ray& s = rayAt(i);
            HitCollector hc;
            rtcInitIntersectContext(&hc.ctx);
            hc.ctx.filter = &collectAllHits;
            hc.hits = buffer.data();
            hc.capacity = 48;
            RTCRayHit rh{};
            rh.ray = ray1(s, s.tfar);
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene, &hc.ctx, &rh);
            visited += hc.visited;
        }
        return visited;
    }
};

// Runs `body` over n rays kRepeats times and writes out[name]: the median time counts
// (other load on a shared machine skews single runs). The first, untimed pass warms up.
// metric: body's count per ray.
template <class Body>
void measure(nlohmann::json& out, const char* name, uint64_t n, uint64_t grain, Body body) {
    constexpr int kRepeats = 3;
    std::vector<double> times;
    double metric = 0;
    for (int rep = -1; rep < kRepeats; ++rep) {
        std::atomic<uint64_t> total{0};
        const uint64_t count = rep < 0 ? std::min<uint64_t>(n, 100000) : n;
        const auto t = std::chrono::steady_clock::now();
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, count, grain), [&](const tbb::blocked_range<uint64_t>& r) {
            const FloatModeScope ftz(FloatModeScope::Underflow::FlushToZero);  // as the stage
            total += body(r.begin(), r.end());
        });
        if (rep >= 0) times.push_back(secondsSince(t));
        metric = double(total) / double(count);
    }
    std::sort(times.begin(), times.end());
    const double median = times[times.size() / 2];
    out[name] = {{"seconds", median}, {"raysPerSecond", double(n) / median}, {"metric", metric}, {"allSeconds", times}};
}

}  // namespace

// See the file comment. `centre`: the chunk whose window is traced (with its neighbours as
// in a bake); `rays`: how many rays each loop traces (0: the list once); `threads`: 0 = all;
// `lightWeights`: per light, its share of the rays (empty: every ray of every light alike).
nlohmann::json runEmbreeBaseline(const std::string& spaceDir, int centreX, int centreZ, uint64_t rays, int threads,
                                 const std::vector<double>& lightWeights) {
    using nlohmann::json;
    json out;
    std::unique_ptr<tbb::global_control> limit;
    if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));

    const std::vector<ChunkCoord> only{{centreX, centreZ}};
    Expected<Space> loaded = loadSpace(spaceDir, "", &only);
    if (!loaded) {
        out["error"] = loaded.error().what();
        return out;
    }
    TerrainMeshes terrainMeshes;
    const BakeWindow w = buildWindow(*loaded, only[0], terrainMeshes);

    const std::string config = threads > 0 ? "threads=" + std::to_string(threads) : "";
    RTCDevice device = rtcNewDevice(config.c_str());
    if (!device) {
        out["error"] = "Embree device could not be created";
        return out;
    }
    const auto tBuild = std::chrono::steady_clock::now();
    // The stage's own scene code (raycast/embree_scene.h), so both trace the same scene.
    auto scenes = std::make_unique<raycast::EmbreeScenes>(device);
    raycast::WindowScene windowScene = scenes->buildWindow(w);
    RTCScene scene = windowScene.all();
    uint64_t windowTriangles = 0;
    std::unordered_set<const Mesh*> uniqueMeshes;
    for (const WindowObject& o : w.objects) {
        windowTriangles += o.mesh->triangles.size();
        if (o.kind != ChunkObject::Kind::Terrain) uniqueMeshes.insert(o.mesh);
    }
    const double buildSeconds = secondsSince(tBuild);

    uint64_t centreGroups = 0, available = 0;
    json mix;
    const std::vector<Ray> list = mixedRays(w, stageRays(w, centreGroups), lightWeights, mix, available);
    out["window"] = {{"objects", w.objects.size()}, {"triangles", windowTriangles}, {"uniqueMeshes", uniqueMeshes.size()},
                     {"centreGroups", centreGroups}, {"raysAvailable", available}, {"rayList", list.size()},
                     {"mix", mix}, {"buildSeconds", buildSeconds}};
    if (list.empty()) {
        out["error"] = "no rays in the window";
        return out;
    }
    const uint64_t n = rays > 0 ? rays : list.size();
    out["rays"] = n;
    const Loops loops{w, scene, list};
    measure(out, "occluded1", n, 4096, [&](uint64_t b, uint64_t e) { return loops.occluded1(b, e, true); });
    // For reference only.
    measure(out, "occluded1Full", n, 4096, [&](uint64_t b, uint64_t e) { return loops.occluded1(b, e, false); });
    measure(out, "occluded16", n, 256, [&](uint64_t b, uint64_t e) { return loops.occluded16(b, e); });
    measure(out, "closest1", n, 4096, [&](uint64_t b, uint64_t e) { return loops.closest1(b, e); });
    measure(out, "allhits1", n, 1024, [&](uint64_t b, uint64_t e) { return loops.allHits1(b, e); });
    windowScene.reset();
    scenes.reset();  // its prototypes, before the device
    rtcReleaseDevice(device);
    return out;
}

}  // namespace shadowcull::bench
