// The window's triangles in one vertex buffer for the plain (non-conservative) passes: the
// baseline method and the light-view render. Window-local positions as floats, grouped by
// (object, primitive group) so that each group is one draw call.
#pragma once

#include <vector>

#include "gpu/gl_api.h"
#include "gpu/light_view.h"

namespace shadowcull::gpu {

struct GroupRange {
    uint32_t object = 0;  // index into BakeWindow::objects
    uint32_t group = 0;
    GLint first = 0;      // first vertex
    GLsizei count = 0;    // vertices (3 per triangle)
};

// Vertex shader of the plain passes: window-local position aPos through uClip, passed on as
// vPos (window-local) for the fragment shader.
extern const char* const kWindowPositionVs;

class WindowBuffers {
public:
    Status upload(const GlApi& gl, const BakeWindow& w, const WindowTriangles& tris);
    void destroy(const GlApi& gl);
    void bind(const GlApi& gl) const { gl.BindVertexArray(vao_); }
    const std::vector<GroupRange>& ranges() const { return ranges_; }

private:
    GLuint vao_ = 0, vbo_ = 0;
    std::vector<GroupRange> ranges_;
};

// Window-local bounds of each primitive group of window object `object` (of its triangles
// with three distinct vertices; empty for a group without any).
std::vector<Aabb> groupBounds(const BakeWindow& w, const WindowTriangles& tris, size_t object);

// A float texture (R32F) holding, over the window's x-z rectangle seen from above, the
// lowest terrain surface (window-local y), +1e30 where there is no terrain.
struct TerrainHeightMap {
    GLuint texture = 0;
    double x0 = 0, z0 = 0, x1 = 1, z1 = 1;  // window-local rectangle the texture spans
};

// Renders the terrain objects of the window from above into a heightmap (resolution x
// resolution texels; each texel holds the terrain height at its centre, as rasterised).
Expected<TerrainHeightMap> renderTerrainHeights(const GlApi& gl, const BakeWindow& w, const WindowBuffers& buffers,
                                                int resolution);

}  // namespace shadowcull::gpu
