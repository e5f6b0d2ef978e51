#include "raycast/embree_scene.h"

#include <pmmintrin.h>
#include <xmmintrin.h>

namespace shadowcull::raycast {

namespace {

// Triangle geometry with vertices given by `place` (float, as Embree wants them).
template <class Place>
RTCGeometry makeTriangles(RTCDevice device, const Mesh& mesh, Place place) {
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.positions.size()));
    auto* ix = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(unsigned), mesh.triangles.size()));
    if (!v || !ix) return geom;
    for (size_t k = 0; k < mesh.positions.size(); ++k) {
        glm::dvec3 p = place(mesh.positions[k]);
        v[3 * k] = float(p.x);
        v[3 * k + 1] = float(p.y);
        v[3 * k + 2] = float(p.z);
    }
    for (size_t k = 0; k < mesh.triangles.size(); ++k)
        for (int c = 0; c < 3; ++c) ix[3 * k + size_t(c)] = mesh.triangles[k][size_t(c)];
    rtcCommitGeometry(geom);
    return geom;
}

}  // namespace

EmbreeScenes::~EmbreeScenes() {
    for (auto& [mesh, scene] : prototypes_) rtcReleaseScene(scene);
}

RTCScene EmbreeScenes::prototype(const Mesh* mesh) {
    auto it = prototypes_.find(mesh);
    if (it != prototypes_.end()) return it->second;
    RTCScene s = rtcNewScene(device_);
    rtcSetSceneFlags(s, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    RTCGeometry g = makeTriangles(device_, *mesh, [](const glm::dvec3& p) { return p; });
    rtcAttachGeometryByID(s, g, 0);
    rtcReleaseGeometry(g);
    rtcCommitScene(s);
    prototypes_.emplace(mesh, s);
    return s;
}

RTCScene EmbreeScenes::buildWindow(const BakeWindow& w) {
    RTCScene scene = rtcNewScene(device_);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    for (size_t k = 0; k < w.objects.size(); ++k) {
        const WindowObject& o = w.objects[k];
        RTCGeometry g;
        if (o.kind == ChunkObject::Kind::Terrain) {
            g = makeTriangles(device_, *o.mesh, [&](const glm::dvec3& p) { return o.lsTransform.apply(p); });
        } else {
            g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
            rtcSetGeometryInstancedScene(g, prototype(o.mesh));
            // Column-major 3x4: the columns are our rows (p' = p.x r0 + p.y r1 + p.z r2 + r3).
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
    return scene;
}

void skipAlphaTested(const RTCFilterFunctionNArguments* args) {
    const auto* a = reinterpret_cast<const AlphaSkip*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (!args->valid[i]) continue;
        const uint32_t object = hitObject(RTCHitN_instID(args->hit, args->N, i, 0), RTCHitN_geomID(args->hit, args->N, i));
        const WindowObject& o = a->window->objects[object];
        const uint32_t group = o.mesh->triangleGroup[RTCHitN_primID(args->hit, args->N, i)];
        if (o.mesh->groups[group].alphaTested && !(object == a->object && group == a->group)) args->valid[i] = 0;
    }
}

void enableFlushToZero() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

}  // namespace shadowcull::raycast
