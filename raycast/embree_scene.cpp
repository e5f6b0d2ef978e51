#include "raycast/embree_scene.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>


namespace shadowcull::raycast {

namespace {

// Triangle geometry of the mesh's triangles `subset` (all when empty), vertices given by
// `place` (float, as Embree wants them).
template <class Place>
RTCGeometry makeTriangles(RTCDevice device, const Mesh& mesh, const std::vector<uint32_t>& subset, Place place) {
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    const size_t count = subset.empty() ? mesh.triangles.size() : subset.size();
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.positions.size()));
    auto* ix = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), count));
    if (!v || !ix) return geom;
    for (size_t k = 0; k < mesh.positions.size(); ++k) {
        glm::dvec3 p = place(mesh.positions[k]);
        v[3 * k] = float(p.x);
        v[3 * k + 1] = float(p.y);
        v[3 * k + 2] = float(p.z);
    }
    for (size_t k = 0; k < count; ++k) {
        const auto& tri = mesh.triangles[subset.empty() ? k : subset[k]];
        for (int c = 0; c < 3; ++c) ix[3 * k + size_t(c)] = tri[size_t(c)];
    }
    rtcCommitGeometry(geom);
    return geom;
}

}  // namespace

void EmbreeScenes::release(Prototype& proto) {
    if (proto.opaque && proto.opaque != proto.all) rtcReleaseScene(proto.opaque);
    rtcReleaseScene(proto.all);
    proto = {};
}

EmbreeScenes::~EmbreeScenes() {
    for (auto& [mesh, proto] : prototypes_) release(proto);
}

void EmbreeScenes::forget(const std::unordered_set<const Mesh*>& meshes) {
    for (const Mesh* m : meshes) {
        if (auto it = prototypes_.find(m); it != prototypes_.end()) {
            release(it->second);
            prototypes_.erase(it);
        }
        full_.erase(m);  // the address may come back as another mesh
    }
}

EmbreeScenes::Prototype EmbreeScenes::buildPrototype(const Mesh* mesh, bool terrain) const {
    Prototype proto;
    if (terrain && !mesh->positions.empty()) {
        // Whole metres: exact in the instance's float translation, and the same floats
        // for a terrain lifted by whole metres.
        double lo = mesh->positions[0].y, hi = lo;
        for (const glm::dvec3& p : mesh->positions) {
            lo = std::min(lo, p.y);
            hi = std::max(hi, p.y);
        }
        proto.offset.y = std::round(0.5 * (lo + hi));
    }
    const glm::dvec3 offset = proto.offset;
    proto.compact = !terrain && mesh->triangles.size() >= kCompactFrom && !full_.count(mesh);
    proto.raysAtBuild = rays_;
    const RTCSceneFlags flags = RTCSceneFlags(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION |
                                              (proto.compact ? RTC_SCENE_FLAG_COMPACT : RTC_SCENE_FLAG_NONE));
    auto makeScene = [&](const std::vector<uint32_t>& subset) {
        RTCScene s = rtcNewScene(device_);
        rtcSetSceneFlags(s, flags);
        RTCGeometry g = makeTriangles(device_, *mesh, subset, [&](const glm::dvec3& p) { return p - offset; });
        rtcAttachGeometryByID(s, g, 0);
        rtcReleaseGeometry(g);
        rtcCommitScene(s);
        return s;
    };
    proto.all = makeScene({});
    std::vector<uint32_t> opaque;
    for (uint32_t t = 0; t < mesh->triangles.size(); ++t)
        if (!mesh->groups[mesh->triangleGroup[t]].alphaTested) opaque.push_back(t);
    if (opaque.size() == mesh->triangles.size()) {
        proto.opaque = proto.all;
    } else if (!opaque.empty()) {
        proto.opaque = makeScene(opaque);
        proto.opaqueTriangles = std::make_shared<const std::vector<uint32_t>>(std::move(opaque));
    }
    return proto;
}

void EmbreeScenes::buildPrototypes(const BakeWindow& w) {
    // The meshes without one, once each, in window order; built in parallel (a window that
    // slid brings a row of terrains, each a small build that Embree runs on one thread).
    std::vector<std::pair<const Mesh*, bool>> missing;
    std::unordered_set<const Mesh*> seen;
    for (const WindowObject& o : w.objects)
        if (!prototypes_.count(o.mesh) && seen.insert(o.mesh).second)
            missing.emplace_back(o.mesh, o.kind == ChunkObject::Kind::Terrain);
    std::vector<Prototype> built(missing.size());
    tbb::parallel_for(size_t(0), missing.size(),
                      [&](size_t k) { built[k] = buildPrototype(missing[k].first, missing[k].second); });
    for (size_t k = 0; k < missing.size(); ++k) prototypes_.emplace(missing[k].first, built[k]);
}

RTCScene EmbreeScenes::placeAll(const BakeWindow& w, bool opaque) const {
    RTCScene scene = rtcNewScene(device_);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    for (size_t k = 0; k < w.objects.size(); ++k) {
        const WindowObject& o = w.objects[k];
        if (opaque && !o.castsShadow) continue;  // not in the shadow map: light passes it
        const Prototype& proto = prototypes_.at(o.mesh);  // buildPrototypes made it
        RTCScene placed = opaque ? proto.opaque : proto.all;
        if (!placed) continue;  // nothing opaque in it
        RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, placed);
        // Column-major 3x4: the columns are our rows (p' = p.x r0 + p.y r1 + p.z r2 + r3).
        // Terrain's linear part is the identity, so its offset moves into the translation.
        float xfm[12];
        for (int r = 0; r < 4; ++r) {
            glm::dvec3 row = o.lsTransform.rows[size_t(r)];
            if (r == 3) row += proto.offset;
            for (int c = 0; c < 3; ++c) xfm[3 * r + c] = float(row[c]);
        }
        rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(scene, g, unsigned(k));
        rtcReleaseGeometry(g);
    }
    rtcCommitScene(scene);
    return scene;
}

WindowScene EmbreeScenes::buildWindow(const BakeWindow& w) {
    // Compact prototypes that have had their rays' worth (kFullAfterRays): built again in
    // full when this window places them (a window scene still using the old one holds it).
    for (auto it = prototypes_.begin(); it != prototypes_.end();) {
        const Prototype& p = it->second;
        if (p.compact && rays_ - p.raysAtBuild >= kFullAfterRays * uint64_t(it->first->triangles.size())) {
            full_.insert(it->first);
            release(it->second);
            it = prototypes_.erase(it);
        } else {
            ++it;
        }
    }
    buildPrototypes(w);
    // The two top-level trees side by side (each a few milliseconds that Embree's own
    // threads barely share).
    const bool split = needsTransparencyFilter(w);
    RTCScene all = nullptr, opaque = nullptr;
    tbb::parallel_invoke([&] { all = placeAll(w, false); }, [&] { opaque = split ? placeAll(w, true) : nullptr; });
    std::vector<WindowScene::TriangleMap> opaqueTriangles;
    if (split) {
        opaqueTriangles.reserve(w.objects.size());
        for (const WindowObject& o : w.objects) opaqueTriangles.push_back(prototypes_.at(o.mesh).opaqueTriangles);
    }
    WindowScene scene(all, split ? opaque : all, std::move(opaqueTriangles));
    // The window slid: the prototypes of meshes it no longer holds (the terrains of the
    // chunks left behind) are released, so that memory follows the window, not the world.
    const std::unordered_set<const Mesh*> loaded = w.meshes();
    for (auto it = prototypes_.begin(); it != prototypes_.end();) {
        if (loaded.count(it->first)) {
            ++it;
        } else {
            release(it->second);
            it = prototypes_.erase(it);
        }
    }
    return scene;
}

void skipTransparent(const RTCFilterFunctionNArguments* args) {
    const auto* a = reinterpret_cast<const TransparentSkip*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (!args->valid[i]) continue;
        const uint32_t object = hitObject(RTCHitN_instID(args->hit, args->N, i, 0), RTCHitN_geomID(args->hit, args->N, i));
        const WindowObject& o = a->window->objects[object];
        const uint32_t group = o.mesh->triangleGroup[RTCHitN_primID(args->hit, args->N, i)];
        if (!o.blocksLight(group) && !(object == a->object && group == a->group)) args->valid[i] = 0;
    }
}

}  // namespace shadowcull::raycast
