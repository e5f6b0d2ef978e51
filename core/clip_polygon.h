// Sutherland-Hodgman clipping of a convex polygon by one half-space, generic over the
// arithmetic: doubles (geometry/geometry_stage.cpp's bounds, gpu/conservative.cpp's
// view-space clip), CGAL's exact kernel and its interval filter (geometry/exact_frustum.cpp).
// The callers keep what makes their result sound (a slack, an exact sign, a crossing point
// built from a fixed endpoint); this only walks the edges.
//
// I. E. Sutherland, G. W. Hodgman, "Reentrant Polygon Clipping", CACM 17(1), 1974.
#pragma once

#include <cstddef>

namespace shadowcull {

// Emits, in order, the part of the convex polygon in[0], ..., in[n - 1] where the side
// function is not negative: each vertex that is not on the negative side, and after it the
// crossing point of each edge whose ends lie strictly on opposite sides.
//   valueOf(p)              the signed side value at vertex p (evaluated once per vertex,
//                           in order);
//   sideOf(v)               its side: > 0 inside, 0 on the boundary, < 0 outside (may throw:
//                           an interval whose sign is not certain; nothing is emitted after);
//   crossing(p, q, vp, vq)  the point where edge p -> q meets the boundary;
//   emit(point)             receives the result.
// A function whose boundary counts as inside for crossings too maps 0 to a positive side.
template <class Point, class ValueOf, class SideOf, class Crossing, class Emit>
void clipPolygon(const Point* in, size_t n, const ValueOf& valueOf, const SideOf& sideOf, const Crossing& crossing,
                 const Emit& emit) {
    if (n == 0) return;
    const auto firstValue = valueOf(in[0]);
    const int firstSide = sideOf(firstValue);
    auto vp = firstValue;
    int sp = firstSide;
    for (size_t i = 0; i < n; ++i) {
        const size_t j = i + 1 == n ? 0 : i + 1;
        const auto vq = j == 0 ? firstValue : valueOf(in[j]);
        const int sq = j == 0 ? firstSide : sideOf(vq);
        if (sp >= 0) emit(in[i]);
        if ((sp > 0 && sq < 0) || (sp < 0 && sq > 0)) emit(crossing(in[i], in[j], vp, vq));
        vp = vq;
        sp = sq;
    }
}

// The side of a double value where the boundary counts as inside (f >= 0 keeps a point; a
// NaN is outside).
inline int closedSide(double v) { return v >= 0 ? 1 : -1; }

}  // namespace shadowcull
