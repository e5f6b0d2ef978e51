#include "gpu/light_view.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace shadowcull::gpu {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

void lightBasis(const glm::dvec3& W, glm::dvec3& U, glm::dvec3& V) {
    const glm::dvec3 a = glm::abs(W);
    glm::dvec3 axis(1, 0, 0);
    if (a.y < a.x && a.y <= a.z) axis = glm::dvec3(0, 1, 0);
    else if (a.z < a.x && a.z < a.y) axis = glm::dvec3(0, 0, 1);
    U = glm::normalize(axis - W * glm::dot(W, axis));
    V = glm::cross(U, W);  // U x (U x W) = -W
}

glm::dvec3 LightView::toView(const glm::dvec3& p) const {
    if (!perspective) return {glm::dot(p, U), glm::dot(p, V), glm::dot(p, W) - w0};
    const glm::dvec3 d = p - eye;
    return {glm::dot(d, U), glm::dot(d, V), glm::dot(d, W)};
}

glm::dvec2 LightView::viewToPixel(const glm::dvec3& v) const {
    if (!perspective) return {(v.x - u0) / (u1 - u0) * width, (v.y - v0) / (v1 - v0) * height};
    return {(v.x / (v.z * t) + 1) * 0.5 * width, (v.y / (v.z * t) + 1) * 0.5 * height};
}

glm::dvec3 LightView::pointAt(double px, double py, double depth) const {
    if (!perspective) {
        const double u = u0 + px / width * (u1 - u0), v = v0 + py / height * (v1 - v0);
        return U * u + V * v + W * (depth + w0);
    }
    const double x = (2 * px / width - 1) * t, y = (2 * py / height - 1) * t;
    return eye + (U * x + V * y + W) * depth;
}

glm::dvec3 LightView::rayDirection(double px, double py) const {
    if (!perspective) return W;
    const double x = (2 * px / width - 1) * t, y = (2 * py / height - 1) * t;
    return glm::normalize(U * x + V * y + W);
}

double LightView::pixelSize(double depth) const {
    if (!perspective) return std::max((u1 - u0) / width, (v1 - v0) / height);
    // Largest at the frustum's corner: 2t/width in tangent, times sec^2 of the corner angle.
    return 2 * t / std::min(width, height) * (1 + 2 * t * t) * std::max(depth, 0.0);
}

std::array<float, 16> LightView::clipMatrix(double nearZ, double farZ, double depthMargin) const {
    // Rows of the 4x4 matrix acting on (p, 1); stored column-major.
    double r[4][4] = {};
    if (!perspective) {
        const double su = 2 / (u1 - u0), sv = 2 / (v1 - v0);
        const double d0 = w0 - depthMargin, d1 = w1 + depthMargin, sw = 2 / (d1 - d0);
        for (int k = 0; k < 3; ++k) {
            r[0][k] = U[k] * su;
            r[1][k] = V[k] * sv;
            r[2][k] = W[k] * sw;
        }
        r[0][3] = -u0 * su - 1;
        r[1][3] = -v0 * sv - 1;
        r[2][3] = -d0 * sw - 1;
        r[3][3] = 1;
    } else {
        // x_clip = x / t, y_clip = y / t, w_clip = z, z_ndc = A + B / z in [-1, 1].
        const double B = -2 * nearZ * farZ / (farZ - nearZ), A = (farZ + nearZ) / (farZ - nearZ);
        for (int k = 0; k < 3; ++k) {
            r[0][k] = U[k] / t;
            r[1][k] = V[k] / t;
            r[2][k] = W[k] * A;
            r[3][k] = W[k];
        }
        r[0][3] = -glm::dot(eye, U) / t;
        r[1][3] = -glm::dot(eye, V) / t;
        r[2][3] = -glm::dot(eye, W) * A + B;
        r[3][3] = -glm::dot(eye, W);
    }
    std::array<float, 16> m{};
    for (int row = 0; row < 4; ++row)
        for (int col = 0; col < 4; ++col) m[size_t(col * 4 + row)] = float(r[row][col]);
    return m;
}

std::vector<LightView> lightViews(const BakeWindow& w, const Light& L, int resolution, const Aabb* lsFocus) {
    std::vector<LightView> views;
    if (w.lsBounds.empty()) return views;
    if (L.type == LightType::Directional) {
        LightView v;
        v.W = glm::normalize(L.direction);
        lightBasis(v.W, v.U, v.V);
        double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
        // The rectangle (k = 0, 1) over the focus when there is one, the depths (k = 2) over
        // the window: every receiver and occluder along a ray through the focus.
        const bool focused = lsFocus && !lsFocus->empty();
        auto extend = [&](const Aabb& box, int k0, int k1) {
            for (int c = 0; c < 8; ++c) {
                const glm::dvec3 p((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y,
                                   (c & 4) ? box.max.z : box.min.z);
                const double q[3] = {glm::dot(p, v.U), glm::dot(p, v.V), glm::dot(p, v.W)};
                for (int k = k0; k <= k1; ++k) {
                    lo[k] = std::min(lo[k], q[k]);
                    hi[k] = std::max(hi[k], q[k]);
                }
            }
        };
        extend(focused ? *lsFocus : w.lsBounds, 0, focused ? 1 : 2);
        if (focused) extend(w.lsBounds, 2, 2);
        // A window flat in one direction of the view still needs a non-empty rectangle.
        const double scale = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-3});
        for (int k = 0; k < 3; ++k)
            if (hi[k] - lo[k] < 1e-6 * scale) {
                lo[k] -= 1e-6 * scale;
                hi[k] += 1e-6 * scale;
            }
        v.u0 = lo[0], v.u1 = hi[0], v.v0 = lo[1], v.v1 = hi[1], v.w0 = lo[2], v.w1 = hi[2];
        v.width = v.height = resolution;
        views.push_back(v);
        return views;
    }
    if (L.type == LightType::Spot && L.coneHalfAngleDeg <= kMaxSingleViewSpotDeg) {
        LightView v;
        v.perspective = true;
        v.eye = L.position;
        v.W = glm::normalize(L.direction);
        lightBasis(v.W, v.U, v.V);
        v.t = std::tan(L.coneHalfAngleDeg * kPi / 180.0);
        v.width = v.height = resolution;
        views.push_back(v);
        return views;
    }
    const glm::dvec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int f = 0; f < 6; ++f) {
        LightView v;
        v.perspective = true;
        v.face = f;
        v.eye = L.position;
        v.W = axes[f];
        lightBasis(v.W, v.U, v.V);
        v.t = 1;
        v.width = v.height = resolution;
        views.push_back(v);
    }
    return views;
}

WindowTriangles::WindowTriangles(const BakeWindow& w)
    : w_(w), objects_(w.objects.size()), once_(std::make_unique<std::once_flag[]>(w.objects.size())) {}

const WindowTriangles::Object& WindowTriangles::object(size_t k) const {
    std::call_once(once_[k], [&] {
        const WindowObject& o = w_.objects[k];
        Object& out = objects_[k];
        out.positions.reserve(o.mesh->positions.size());
        for (const glm::dvec3& p : o.mesh->positions) out.positions.push_back(o.lsTransform.apply(p));
        for (size_t t = 0; t < o.mesh->triangles.size(); ++t) {
            // Same test as everywhere in the project: a repeated vertex (in mesh coordinates).
            if (hasRepeatedVertex(*o.mesh, t)) continue;
            out.triangles.push_back(uint32_t(t));
            for (uint32_t v : o.mesh->triangles[t]) out.lsBounds.extend(out.positions[v]);
        }
    });
    return objects_[k];
}

}  // namespace shadowcull::gpu
