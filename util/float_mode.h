// The calling thread's SSE floating-point mode (MXCSR), set for a scope and restored on
// leaving. TBB runs every stage's tasks on the same worker threads, and a mode left behind
// there reaches the next stage: Embree's BVH builds leave TBB tasks with flush-to-zero and
// denormals-are-zero set (seen with Embree 3.13 and oneTBB 2021.8), which the ray stage
// wants and CGAL's interval filters must not have (a product flushed to zero gives an
// interval that excludes the true value, so a sign could be "certain" and wrong).
#pragma once

#include <xmmintrin.h>

namespace shadowcull {

class FloatModeScope {
public:
    enum class Underflow {
        Gradual,      // IEEE 754: what exact-predicate filters assume
        FlushToZero,  // flush-to-zero and denormals-are-zero: fast ray traversal
    };
    explicit FloatModeScope(Underflow mode) : saved_(_mm_getcsr()) {
        _mm_setcsr(mode == Underflow::FlushToZero ? saved_ | kFtzDaz : saved_ & ~kFtzDaz);
    }
    ~FloatModeScope() { _mm_setcsr(saved_); }
    FloatModeScope(const FloatModeScope&) = delete;
    FloatModeScope& operator=(const FloatModeScope&) = delete;

    static constexpr unsigned int kFtzDaz = 0x8040;  // MXCSR bits 15 (FTZ) and 6 (DAZ)
    // The calling thread's mode: for the tasks it hands to other threads, which may be in
    // another (a scope of current() in each keeps the work in the caller's mode).
    static Underflow current() {
        return (_mm_getcsr() & kFtzDaz) == kFtzDaz ? Underflow::FlushToZero : Underflow::Gradual;
    }

private:
    unsigned int saved_;
};

}  // namespace shadowcull
