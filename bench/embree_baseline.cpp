// The bare Embree loop that the pipeline's raycast stage is compared with (issue 6: "rays/s
// at least half of a bare Embree occlusion loop over the same scene").
//
// The scene is built exactly as raycast/raycast_stage.cpp builds a window's scene: one
// Embree scene per mesh resource (RTC_SCENE_FLAG_ROBUST | CONTEXT_FILTER_FUNCTION), placed
// by instances, terrain as plain triangles in window-local floats. The rays are the ones
// the stage would cast in that window: for every primitive group of the centre chunk and
// every light that reaches it, rays from the light through the group's sample points
// (raycast::sampleGroup, 256 area + up to 1024 feature samples); directional rays start
// before the loaded bounds and cross the whole window, like the stage's. The loops cycle
// through that list until `rays` rays have been traced, in parallel over TBB:
//
//  - occluded1:  rtcOccluded1, one ray at a time (any hit ends the ray)
//  - occluded16: rtcOccluded16, packets of 16 consecutive rays (same group and light)
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
#include <unordered_map>
#include <vector>

#include <embree3/rtcore.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <pmmintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <xmmintrin.h>

#include "core/scene.h"
#include "core/window.h"
#include "raycast/group_samples.h"

namespace shadowcull::bench {

namespace {

struct Ray {
    float org[3], dir[3], tfar;
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

// The stage's context for finding p (raycast_stage.cpp, reproduced): light passes
// alpha-tested groups other than the target group.
struct AlphaSkip {
    RTCIntersectContext ctx;
    const BakeWindow* window = nullptr;
    uint32_t object = 0, group = 0;
};

void skipAlphaTested(const RTCFilterFunctionNArguments* args) {
    const auto* a = reinterpret_cast<const AlphaSkip*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (!args->valid[i]) continue;
        const unsigned inst = RTCHitN_instID(args->hit, args->N, i, 0);
        const uint32_t object = inst != RTC_INVALID_GEOMETRY_ID ? inst : RTCHitN_geomID(args->hit, args->N, i);
        const WindowObject& o = a->window->objects[object];
        const uint32_t group = o.mesh->triangleGroup[RTCHitN_primID(args->hit, args->N, i)];
        if (o.mesh->groups[group].alphaTested && !(object == a->object && group == a->group)) args->valid[i] = 0;
    }
}

void enableFlushToZero() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

template <class Place>
RTCGeometry makeTriangles(RTCDevice device, const Mesh& mesh, Place place) {
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.positions.size()));
    auto* ix = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(unsigned), mesh.triangles.size()));
    for (size_t k = 0; k < mesh.positions.size(); ++k) {
        const glm::dvec3 p = place(mesh.positions[k]);
        v[3 * k] = float(p.x);
        v[3 * k + 1] = float(p.y);
        v[3 * k + 2] = float(p.z);
    }
    for (size_t k = 0; k < mesh.triangles.size(); ++k)
        for (int c = 0; c < 3; ++c) ix[3 * k + size_t(c)] = mesh.triangles[k][size_t(c)];
    rtcCommitGeometry(geom);
    return geom;
}

double secondsSince(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

// See the file comment. `centre`: the chunk whose window is traced (with its neighbours as
// in a bake); `rays`: how many rays each loop traces (0: the list once); `threads`: 0 = all.
nlohmann::json runEmbreeBaseline(const std::string& spaceDir, int centreX, int centreZ, uint64_t rays, int threads) {
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
    std::vector<std::pair<const Heightfield*, std::shared_ptr<const Mesh>>> terrainMeshes;
    const BakeWindow w = buildWindow(*loaded, only[0], terrainMeshes);

    const std::string config = threads > 0 ? "threads=" + std::to_string(threads) : "";
    RTCDevice device = rtcNewDevice(config.c_str());
    if (!device) {
        out["error"] = "Embree device could not be created";
        return out;
    }
    const auto tBuild = std::chrono::steady_clock::now();
    std::unordered_map<const Mesh*, RTCScene> prototypes;
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    uint64_t windowTriangles = 0;
    for (size_t k = 0; k < w.objects.size(); ++k) {
        const WindowObject& o = w.objects[k];
        windowTriangles += o.mesh->triangles.size();
        RTCGeometry g;
        if (o.kind == ChunkObject::Kind::Terrain) {
            g = makeTriangles(device, *o.mesh, [&](const glm::dvec3& p) { return o.lsTransform.apply(p); });
        } else {
            RTCScene& proto = prototypes[o.mesh];
            if (!proto) {
                proto = rtcNewScene(device);
                rtcSetSceneFlags(proto, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
                RTCGeometry pg = makeTriangles(device, *o.mesh, [](const glm::dvec3& p) { return p; });
                rtcAttachGeometryByID(proto, pg, 0);
                rtcReleaseGeometry(pg);
                rtcCommitScene(proto);
            }
            g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
            rtcSetGeometryInstancedScene(g, proto);
            float xfm[12];
            for (int r = 0; r < 4; ++r)
                for (int c = 0; c < 3; ++c) xfm[3 * r + c] = float(o.lsTransform.rows[size_t(r)][c]);
            rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm);
            rtcCommitGeometry(g);
        }
        rtcAttachGeometryByID(scene, g, unsigned(k));
        rtcReleaseGeometry(g);
    }
    rtcCommitScene(scene);
    const double buildSeconds = secondsSince(tBuild);

    // The stage's rays: per centre group and reaching light, through its sample points.
    const double diag = glm::length(w.lsBounds.max - w.lsBounds.min);
    const double backDist = diag + 1.0;
    std::vector<Ray> list;
    uint64_t centreGroups = 0;
    for (uint32_t oi = 0; oi < w.objects.size(); ++oi) {
        const WindowObject& o = w.objects[oi];
        if (!o.centre || !o.source->castsShadow) continue;
        for (uint32_t g = 0; g < o.mesh->groups.size(); ++g) {
            const std::vector<glm::dvec3> samples = raycast::sampleGroup(o, g, 256, 1024);
            if (samples.empty()) continue;
            ++centreGroups;
            for (const Light& L : w.lsLights) {
                for (const glm::dvec3& s : samples) {
                    Ray r;
                    glm::dvec3 origin, dir;
                    double tfar;
                    if (L.type == LightType::Directional) {
                        dir = L.direction;
                        origin = s - dir * backDist;
                        tfar = 2 * backDist;
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
                    }
                    for (int c = 0; c < 3; ++c) {
                        r.org[c] = float(origin[c]);
                        r.dir[c] = float(dir[c]);
                    }
                    r.tfar = float(tfar);
                    r.object = oi;
                    r.group = g;
                    list.push_back(r);
                }
            }
        }
    }
    out["window"] = {{"objects", w.objects.size()}, {"triangles", windowTriangles}, {"uniqueMeshes", prototypes.size()},
                     {"centreGroups", centreGroups}, {"rayList", list.size()}, {"buildSeconds", buildSeconds}};
    if (list.empty()) {
        out["error"] = "no rays in the window";
        return out;
    }
    const uint64_t n = rays > 0 ? rays : list.size();
    out["rays"] = n;
    const size_t L = list.size();
    auto rayAt = [&](uint64_t i) -> const Ray& { return list[size_t(i % L)]; };

    // rtcOccluded1.
    {
        std::atomic<uint64_t> occluded{0};
        const auto t = std::chrono::steady_clock::now();
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 4096), [&](const tbb::blocked_range<uint64_t>& r) {
            enableFlushToZero();
            RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            uint64_t local = 0;
            for (uint64_t i = r.begin(); i < r.end(); ++i) {
                const Ray& s = rayAt(i);
                RTCRay ray{};
                ray.org_x = s.org[0], ray.org_y = s.org[1], ray.org_z = s.org[2];
                ray.dir_x = s.dir[0], ray.dir_y = s.dir[1], ray.dir_z = s.dir[2];
                ray.tnear = 0.0f;
                ray.tfar = s.tfar;
                ray.mask = 0xffffffffu;
                rtcOccluded1(scene, &ctx, &ray);
                local += ray.tfar < 0;  // Embree sets tfar to -inf when occluded
            }
            occluded += local;
        });
        const double s = secondsSince(t);
        out["occluded1"] = {{"seconds", s}, {"raysPerSecond", double(n) / s}, {"occludedFraction", double(occluded) / double(n)}};
    }
    // rtcOccluded16: packets of 16 consecutive rays of the list.
    {
        const uint64_t packets = (n + 15) / 16;
        const auto t = std::chrono::steady_clock::now();
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, packets, 256), [&](const tbb::blocked_range<uint64_t>& r) {
            enableFlushToZero();
            RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            alignas(64) RTCRay16 p;
            alignas(64) int valid[16];
            for (uint64_t q = r.begin(); q < r.end(); ++q) {
                for (int k = 0; k < 16; ++k) {
                    const uint64_t i = q * 16 + uint64_t(k);
                    valid[k] = i < n ? -1 : 0;
                    const Ray& s = rayAt(i);
                    p.org_x[k] = s.org[0], p.org_y[k] = s.org[1], p.org_z[k] = s.org[2];
                    p.dir_x[k] = s.dir[0], p.dir_y[k] = s.dir[1], p.dir_z[k] = s.dir[2];
                    p.tnear[k] = 0.0f;
                    p.tfar[k] = s.tfar;
                    p.mask[k] = 0xffffffffu;
                    p.time[k] = 0.0f;
                    p.id[k] = unsigned(k);
                    p.flags[k] = 0;
                }
                rtcOccluded16(valid, scene, &ctx, &p);
            }
        });
        const double s = secondsSince(t);
        out["occluded16"] = {{"seconds", s}, {"raysPerSecond", double(n) / s}};
    }
    // rtcIntersect1 with the stage's alpha-skip filter (closest opaque hit).
    {
        std::atomic<uint64_t> onTarget{0};
        const auto t = std::chrono::steady_clock::now();
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 4096), [&](const tbb::blocked_range<uint64_t>& r) {
            enableFlushToZero();
            uint64_t local = 0;
            for (uint64_t i = r.begin(); i < r.end(); ++i) {
                const Ray& s = rayAt(i);
                AlphaSkip skip;
                rtcInitIntersectContext(&skip.ctx);
                if (w.hasAlphaTested) {
                    skip.ctx.filter = &skipAlphaTested;
                    skip.window = &w;
                    skip.object = s.object;
                    skip.group = s.group;
                }
                RTCRayHit rh{};
                rh.ray.org_x = s.org[0], rh.ray.org_y = s.org[1], rh.ray.org_z = s.org[2];
                rh.ray.dir_x = s.dir[0], rh.ray.dir_y = s.dir[1], rh.ray.dir_z = s.dir[2];
                rh.ray.tnear = 0.0f;
                rh.ray.tfar = s.tfar;
                rh.ray.mask = 0xffffffffu;
                rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                rtcIntersect1(scene, &skip.ctx, &rh);
                const unsigned object = rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID ? rh.hit.instID[0] : rh.hit.geomID;
                local += object == s.object;
            }
            onTarget += local;
        });
        const double s = secondsSince(t);
        out["closest1"] = {{"seconds", s}, {"raysPerSecond", double(n) / s}, {"firstHitOnTarget", double(onTarget) / double(n)}};
    }
    // rtcIntersect1 with an all-hit filter (48 nearest hits): the stage's earlier method.
    {
        std::atomic<uint64_t> hits{0}, visited{0};
        const auto t = std::chrono::steady_clock::now();
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 1024), [&](const tbb::blocked_range<uint64_t>& r) {
            enableFlushToZero();
            std::vector<Hit> buffer(48);
            uint64_t local = 0, localVisited = 0;
            for (uint64_t i = r.begin(); i < r.end(); ++i) {
                const Ray& s = rayAt(i);
                HitCollector hc;
                rtcInitIntersectContext(&hc.ctx);
                hc.ctx.filter = &collectAllHits;
                hc.hits = buffer.data();
                hc.capacity = 48;
                RTCRayHit rh{};
                rh.ray.org_x = s.org[0], rh.ray.org_y = s.org[1], rh.ray.org_z = s.org[2];
                rh.ray.dir_x = s.dir[0], rh.ray.dir_y = s.dir[1], rh.ray.dir_z = s.dir[2];
                rh.ray.tnear = 0.0f;
                rh.ray.tfar = s.tfar;
                rh.ray.mask = 0xffffffffu;
                rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                rtcIntersect1(scene, &hc.ctx, &rh);
                local += uint64_t(hc.count);
                localVisited += hc.visited;
            }
            hits += local;
            visited += localVisited;
        });
        const double s = secondsSince(t);
        out["allhits1"] = {{"seconds", s}, {"raysPerSecond", double(n) / s}, {"meanHitsKept", double(hits) / double(n)},
                           {"meanHitsVisited", double(visited) / double(n)}};
    }
    rtcReleaseScene(scene);
    for (auto& [mesh, proto] : prototypes) rtcReleaseScene(proto);
    rtcReleaseDevice(device);
    return out;
}

}  // namespace shadowcull::bench
