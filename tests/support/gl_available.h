// Whether this machine can make an offscreen OpenGL context on the chosen backend
// (SHADOWCULL_GL, default auto: EGL, then OSMesa), for tests that need one: REQUIRE_GL()
// skips the test, saying why, where none can be made.
#pragma once

#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "gpu/gl_context.h"

namespace shadowcull::testing {

// Empty when a context can be made; else why not (asked once per process).
inline const std::string& glUnavailableReason() {
    static const std::string reason = [] {
        Expected<std::unique_ptr<gpu::GlContext>> ctx = gpu::createOffscreenContext(4, 4);
        return ctx ? std::string() : ctx.error().what();
    }();
    return reason;
}

}  // namespace shadowcull::testing

#define REQUIRE_GL()                                                                                            \
    do {                                                                                                        \
        if (!::shadowcull::testing::glUnavailableReason().empty())                                              \
            GTEST_SKIP() << "no offscreen OpenGL context can be made here ("                                   \
                         << ::shadowcull::testing::glUnavailableReason()                                        \
                         << "); install libegl-mesa0 (Mesa llvmpipe) to run the GPU tests";                       \
    } while (0)
