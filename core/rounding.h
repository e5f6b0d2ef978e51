// Rounding-error bounds for the double-precision shortcuts in front of exact tests, derived
// in one place. A double operation rounds its exact result by a relative error of at most
// the unit roundoff u = 2^-53; a value computed by n operations in sequence carries a
// relative error of at most gamma(n) = n u / (1 - n u) (N. J. Higham, "Accuracy and
// Stability of Numerical Algorithms", 2nd ed., SIAM 2002, lemma 3.1; as pbrt-v4's
// gamma(n): M. Pharr, W. Jakob, G. Humphreys, "Physically Based Rendering", 4th ed., 6.8).
// A bound built from gamma() is a bound on the rounding alone: callers add it on the side
// of keeping (a receiver kept, a witness refused), never the other way.
#pragma once

namespace shadowcull {

constexpr double kUnitRoundoff = 0x1p-53;

// The relative error bound of n rounded operations (n >= 0, n u < 1).
constexpr double gamma(int n) { return n * kUnitRoundoff / (1 - n * kUnitRoundoff); }

}  // namespace shadowcull
