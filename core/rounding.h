// Rounding-error bounds for the double-precision shortcuts in front of exact tests, derived
// in one place. A double operation rounds its exact result by a relative error of at most
// the unit roundoff u = 2^-53; a value computed by n operations in sequence carries a
// relative error of at most gamma(n) = n u / (1 - n u) (N. J. Higham, "Accuracy and
// Stability of Numerical Algorithms", 2nd ed., SIAM 2002, lemma 3.1; as pbrt-v4's
// gamma(n): M. Pharr, W. Jakob, G. Humphreys, "Physically Based Rendering", 4th ed., 6.8).
// A bound built from gamma() is a bound on the rounding alone: callers add it on the side
// of keeping (a receiver kept, a witness refused), never the other way.
//
// Bounded: the one certain-sign helper of the pre-filters. A double computed from exact
// doubles carries a bound on its distance from the exact value of the same expression,
// propagated operation by operation from the operations and the magnitudes of their inputs
// (running error analysis, Higham 3.3; the same bound CGAL's static filters precompute
// per predicate, here evaluated alongside). Rules, for round-to-nearest (the caller's mode:
// never inside CGAL::Protect_FPU_rounding), x = x* + a, |a| <= ex, likewise y:
//   fl(w) = w + r with |r| <= u |fl(w)| for a normal result (Higham 2.5: fl(w) = w / (1 + d),
//   |d| <= u), |r| <= 2^-1075 below the normal range; both within u |fl(w)| + kTiny;
//   z = fl(x +- y):  |z - (x* +- y*)| <= ex + ey + u |z| + kTiny
//   z = fl(x * y):   |z - x* y*| <= |x| ey + |y| ex + ex ey + u |z| + kTiny
//     (x* y* = x y + x b + y a + a b);
// the error itself is a sum of at most 7 rounded non-negative terms and products, so its
// computed value is at least the exact one divided by (1 + u)^7: it is multiplied by the
// double 1 + 8u >= (1 + u)^7 (rounded once more, covered by the same factor's slack).
// A sign is certain when |value| > error: then the exact value has the value's sign.
#pragma once

#include <cmath>

#include <glm/vec3.hpp>

namespace shadowcull {

constexpr double kUnitRoundoff = 0x1p-53;

// The relative error bound of n rounded operations (n >= 0, n u < 1).
constexpr double gamma(int n) { return n * kUnitRoundoff / (1 - n * kUnitRoundoff); }

// The relative allowance for an affine map of a box (RowTransform::apply, then at most one
// dot product), against its magnitude (the sum of its terms' absolute values): apply rounds
// each coordinate within gamma(4) of it (three products and three sums), a following dot
// within gamma(3) more; the bound that stands for the extreme over a box is itself computed
// with at most eleven rounded operations on the same terms: gamma(7) + gamma(11) < gamma(24),
// the rest for the bound's own last sum.
constexpr double kPlacementRounding = gamma(24);

// A computed double and a bound on |value - exact| (see above). Built from exact doubles
// with exactly(); the error is valid while every operation ran in round-to-nearest.
struct Bounded {
    double value = 0;
    double error = 0;
};

namespace rounding_detail {
// The absolute rounding of a result below the normal range (2^-1075), widely: kept a
// normal number so that the bound's own arithmetic never meets a subnormal operand.
constexpr double kTiny = 0x1p-1020;
// (1 + u)^7 <= 1 + 8u: the bound's own rounding (see above).
constexpr double kGrow = 1 + 8 * kUnitRoundoff;
}  // namespace rounding_detail

constexpr Bounded exactly(double v) { return {v, 0.0}; }

inline Bounded operator+(const Bounded& x, const Bounded& y) {
    const double z = x.value + y.value;
    return {z, (x.error + y.error + kUnitRoundoff * std::abs(z) + rounding_detail::kTiny) * rounding_detail::kGrow};
}
inline Bounded operator-(const Bounded& x, const Bounded& y) {
    const double z = x.value - y.value;
    return {z, (x.error + y.error + kUnitRoundoff * std::abs(z) + rounding_detail::kTiny) * rounding_detail::kGrow};
}
inline Bounded operator-(const Bounded& x) { return {-x.value, x.error}; }
inline Bounded operator*(const Bounded& x, const Bounded& y) {
    const double z = x.value * y.value;
    return {z, (std::abs(x.value) * y.error + std::abs(y.value) * x.error + x.error * y.error + kUnitRoundoff * std::abs(z) +
                rounding_detail::kTiny) *
                   rounding_detail::kGrow};
}

// How far along a line a float ray tracer's hit may lie from the line's exact crossing
// with the hit triangle's plane. The hit point lies within `offPlane` of that plane,
// measured along its normal (float copies of the triangle and of the line, each within a
// known distance of the exact ones); a point that far off the plane lies offPlane / |cos|
// from the crossing along a line at angle theta to the normal (cosAbs = |cos theta|). On a
// triangle seen nearly edge-on the float distance is that much worse than its position
// (1 mm off the plane is 1.4 m along a line at cos 7e-4). Infinite at cos 0: no bound.
inline double alongLineFromPlane(double offPlane, double cosAbs) {
    return cosAbs > 0 ? offPlane / cosAbs : HUGE_VAL;
}

// +1 or -1 when the exact value certainly has that sign, 0 when rounding may decide.
inline int certainSign(const Bounded& b) { return b.value > b.error ? 1 : b.value < -b.error ? -1 : 0; }
// The same with `extra` (>= 0) added to the bound: for inputs known only up to a slack the
// caller bounds (the sum is rounded up by the factor 1 + 4u >= (1 + u)^2).
inline int certainSign(const Bounded& b, double extra) {
    const double e = (b.error + extra) * (1 + 4 * kUnitRoundoff);
    return b.value > e ? 1 : b.value < -e ? -1 : 0;
}

// Vectors of Bounded, for the cross and dot products of the filters.
struct Bounded3 {
    Bounded x, y, z;
    glm::dvec3 value() const { return {x.value, y.value, z.value}; }
    glm::dvec3 error() const { return {x.error, y.error, z.error}; }
};

inline Bounded3 exactly(const glm::dvec3& v) { return {exactly(v.x), exactly(v.y), exactly(v.z)}; }
inline Bounded3 operator-(const Bounded3& a, const Bounded3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Bounded3 operator-(const Bounded3& a) { return {-a.x, -a.y, -a.z}; }
// The difference of two exact points: each component rounded once.
inline Bounded3 difference(const glm::dvec3& a, const glm::dvec3& b) { return exactly(a) - exactly(b); }
inline Bounded3 cross(const Bounded3& a, const Bounded3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline Bounded dot(const Bounded3& a, const Bounded3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// The cross product of two vectors, each exact or the rounded difference of two exact
// points (the filters' normals), in closed form: with e1 = fl(b - a) (|e1* - e1| <= u |e1|
// per component; an exact vector has less), fl(e1_y e2_z) is within gamma(3) |e1_y||e2_z|
// of e1*_y e2*_z, and the difference of two such products rounds by u (1 + u) of their sum:
// |n_x - n*_x| <= gamma(4) (|e1_y||e2_z| + |e1_z||e2_y|), likewise y and z. The same bound
// Bounded's rules give, in a third of the operations.
inline Bounded3 crossOfDifferences(const glm::dvec3& e1, const glm::dvec3& e2) {
    const double x = e1.y * e2.z - e1.z * e2.y, y = e1.z * e2.x - e1.x * e2.z, z = e1.x * e2.y - e1.y * e2.x;
    const glm::dvec3 a1(std::abs(e1.x), std::abs(e1.y), std::abs(e1.z)), a2(std::abs(e2.x), std::abs(e2.y), std::abs(e2.z));
    constexpr double g = gamma(4) * rounding_detail::kGrow;
    return {{x, g * (a1.y * a2.z + a1.z * a2.y) + rounding_detail::kTiny},
            {y, g * (a1.z * a2.x + a1.x * a2.z) + rounding_detail::kTiny},
            {z, g * (a1.x * a2.y + a1.y * a2.x) + rounding_detail::kTiny}};
}

// An affine function f(x) = n . (x - o) + k whose normal (and offset) carry Bounded errors,
// evaluated at exact points x with one closed-form bound instead of operation by operation
// (the filters' inner loop). From the rules above: d = fl(x - o) has |d - d*| <= u |d|;
// fl(n_i d_i) is within u (1 + u) |n_i||d_i| of n_i d_i, which is within
// |n_i| u |d_i| + e_i (1 + u) |d_i| of n*_i d*_i (e_i = n's error); the four-term sum with k
// rounds by gamma(3) (|p_0| + |p_1| + |p_2| + |k|) (Higham 3.1). So
//   |f(x) - f*(x)| <= sum_i |d_i| (gamma(6) |n_i| + e_i (1 + gamma(1))) + gamma(3) |k| + k.error,
// with the weights precomputed (rounded up: gamma(6) and 1 + gamma(2)); the bound's own
// evaluation (three products, four sums) is covered by kGrow, underflow by kTiny.
class BoundedPlane {
public:
    BoundedPlane() = default;
    BoundedPlane(const Bounded3& n, const glm::dvec3& o, const Bounded& k) : n_(n.value()), o_(o), k_(k.value) {
        const glm::dvec3 e = n.error();
        weight_ = {gamma(6) * std::abs(n_.x) + e.x * (1 + gamma(2)), gamma(6) * std::abs(n_.y) + e.y * (1 + gamma(2)),
                   gamma(6) * std::abs(n_.z) + e.z * (1 + gamma(2))};
        constant_ = (gamma(4) * std::abs(k_) + k.error) * rounding_detail::kGrow + rounding_detail::kTiny;
    }
    // At an exact point x (a double as given).
    Bounded at(const glm::dvec3& x) const {
        const double dx = x.x - o_.x, dy = x.y - o_.y, dz = x.z - o_.z;
        const double v = n_.x * dx + n_.y * dy + n_.z * dz + k_;
        const double e = weight_.x * std::abs(dx) + weight_.y * std::abs(dy) + weight_.z * std::abs(dz) + constant_;
        return {v, e * rounding_detail::kGrow + rounding_detail::kTiny};
    }
    const glm::dvec3& normal() const { return n_; }

private:
    glm::dvec3 n_{0.0}, o_{0.0};
    double k_ = 0;
    glm::dvec3 weight_{0.0};
    double constant_ = 0;
};

}  // namespace shadowcull
