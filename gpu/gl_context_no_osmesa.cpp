// The OSMesa backend of a build without libOSMesa (gpu/CMakeLists.txt compiles this file
// instead of gl_context_osmesa.cpp): the choice says so and falls through.

#include "gpu/gl_backends.h"

namespace shadowcull::gpu::backends {

Expected<std::unique_ptr<GlContext>> createOsMesaContext(int, int) {
    return makeError(ErrorKind::Internal, "", 0, "this build has no OSMesa (pkg-config found no osmesa, or -DSHADOWCULL_WITHOUT_OSMESA=ON)");
}

}  // namespace shadowcull::gpu::backends
