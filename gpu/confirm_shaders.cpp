// GLSL of the conservative confirmation passes (see confirm_shaders.h).
#include "gpu/confirm_shaders.h"

namespace shadowcull::gpu {

// One instance per piece: the vertex shader places the four corners of the shape that
// covers every pixel the (widened) piece can touch (conservative.h: cover). A geometry
// shader could build it per point, but llvmpipe runs instanced strips several times faster.
const char* const kConfirmRasterVs = R"(#version 430 core
layout(location = 0) in vec4 aBox;
layout(location = 1) in vec4 aE0;
layout(location = 2) in vec4 aE1;
layout(location = 3) in vec4 aE2;
layout(location = 4) in vec4 aPlane;
layout(location = 5) in vec4 aPlane2;
layout(location = 6) in vec4 aMisc;
layout(location = 7) in uint aId;
layout(location = 8) in vec4 aCover01;
layout(location = 9) in vec4 aCover23;
flat out vec4 fBox;
flat out vec4 fE0;
flat out vec4 fE1;
flat out vec4 fE2;
flat out vec4 fPlane;
flat out vec4 fPlane2;
flat out vec4 fMisc;
flat out uint fId;
flat out uint fPiece;  // the piece's index in its draw
uniform vec2 uSize;
void main() {
    fBox = aBox; fE0 = aE0; fE1 = aE1; fE2 = aE2; fPlane = aPlane; fPlane2 = aPlane2; fMisc = aMisc; fId = aId;
    fPiece = uint(gl_InstanceID);
    vec2 c = gl_VertexID == 0 ? aCover01.xy : gl_VertexID == 1 ? aCover01.zw : gl_VertexID == 2 ? aCover23.xy : aCover23.zw;
    gl_Position = vec4(c / uSize * 2.0 - 1.0, 0.0, 1.0);
}
)";

const char* const kConfirmRasterFs = R"(#version 430 core
flat in vec4 fBox;
flat in vec4 fE0;
flat in vec4 fE1;
flat in vec4 fE2;
flat in vec4 fPlane;   // x0, y0, s0, a
flat in vec4 fPlane2;  // b, zmin, zmax, planeValid
flat in vec4 fMisc;    // dilate, margin, kind
flat in uint fId;
flat in uint fPiece;
// The pass: 0 occluder sheet, 1 receivers, 2 caster query (count and record), 3 record only.
// A constant (PASS_MODE is defined before this source), so that each pass's program holds
// only its own branch: llvmpipe runs both sides of a branch on a uniform for every fragment.
const int kMode = PASS_MODE;
uniform bool uPerspective;  // s = 1/z (else s = depth)
uniform float uDepthEps;    // metres, absolute depth margin
uniform float uSizeMax;     // view size in pixels (bounds float rounding of coordinates)
uniform float uBias;        // depth units; already reduced for perspective
uniform bool uAnyReceiver;  // receivers unknown: every pixel may have one behind
uniform uint uRecordCap;
uniform uint uView;
layout(binding = 0) uniform sampler2D uOcc;
layout(binding = 1) uniform sampler2D uRecv;
layout(std430, binding = 0) buffer Counts { uint counts[]; };
layout(std430, binding = 1) buffer Records { uvec4 records[]; };
// Per query: which passed pixels to record (threshold on a hash of the pixel; 0xffffffff
// all, 0 none), the first free record, the records still free, and the fragments offered
// (pixels under the threshold; all of them are recorded when they fit).
layout(std430, binding = 2) buffer Slots { uvec4 slots[]; };
// Per caster piece of the counting draw (mode 2): 1 when a fragment of it passed. Only
// those pieces can record a pixel, so the record-only draws (mode 3) draw only them.
layout(std430, binding = 3) buffer PassedPieces { uint passedPiece[]; };
layout(location = 0) out vec4 oValue;
const float BIG = 1e30;

// Separating axis along one edge normal: the square of half side h around c, widened by
// m, meets the triangle's extent [lo, hi] along n.
bool axisOverlaps(vec4 e, vec2 c, float h, float m) {
    float t = dot(e.xy, c);
    float r = h * (abs(e.x) + abs(e.y)) + m;
    return t + r >= e.z && t - r <= e.w;
}

// Separating axes x, y (the bounding box) and the three edge normals: the square meets the
// piece (a triangle, or a segment whose third edge has length 0).
bool overlaps(vec2 c, float h, float m) {
    float w = h + m;
    if (c.x + w < fBox.x || c.x - w > fBox.z || c.y + w < fBox.y || c.y - w > fBox.w) return false;
    return axisOverlaps(fE0, c, h, m) && axisOverlaps(fE1, c, h, m) && axisOverlaps(fE2, c, h, m);
}

// Point c lies inside the triangle, at least m from each edge's line (and from the
// parallel through the opposite vertex, which only asks more).
bool axisInside(vec4 e, vec2 c, float m) {
    float t = dot(e.xy, c);
    return min(t - e.z, e.w - t) >= m;
}
bool robustInside(vec2 c, float m) { return axisInside(fE0, c, m) && axisInside(fE1, c, m) && axisInside(fE2, c, m); }

// Bounds of the piece's depth over the square of half side h around c: the plane's
// extremes at the square's corners, clamped by the vertices' range, widened by margins.
void depthBounds(vec2 c, float h, out float zlo, out float zhi) {
    zlo = fPlane2.y;
    zhi = fPlane2.z;
    if (fPlane2.w > 0.5) {
        float a = fPlane.w, b = fPlane2.x;
        vec2 d = c - fPlane.xy;
        float sc = fPlane.z + a * d.x + b * d.y;
        float g = abs(a) + abs(b);
        float spread = g * h;
        float err = 1e-6 * (abs(fPlane.z) + g * (abs(d.x) + abs(d.y) + h + abs(fPlane.x) + abs(fPlane.y) + uSizeMax));
        float smin = sc - spread - err, smax = sc + spread + err;
        if (!uPerspective) {
            zlo = max(zlo, smin);
            zhi = min(zhi, smax);
        } else {
            if (smax > 0.0) zlo = max(zlo, 1.0 / smax);
            if (smin > 0.0) zhi = min(zhi, 1.0 / smin);
        }
    }
    zlo -= uDepthEps + 1e-6 * abs(zlo);
    zhi += uDepthEps + 1e-6 * abs(zhi);
}

// A fixed hash of the pixel (view, x, y): which pixels are recorded depends on the pixels
// alone, never on the order in which fragments run.
uint mix32(uint x) {
    x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16;
    return x;
}
bool recorded(ivec2 pix) {
    uint t = slots[fId].x;
    return t == 0xffffffffu || mix32(uint(pix.x) ^ mix32(uint(pix.y) ^ mix32(uView))) < t;
}

void main() {
    vec2 c = gl_FragCoord.xy;
    float m = fMisc.y;
    if (kMode == 0) {
        if (!overlaps(c, 0.5, m)) discard;
        if (fMisc.z > 0.5) {  // a crack edge touches the pixel: this sheet does not cover it whole
            oValue = vec4(BIG, 0.0, 0.0, 0.0);
            return;
        }
        float zlo, zhi;
        depthBounds(c, 0.5 + m, zlo, zhi);
        // Any point of the square robustly inside suffices (the square meets no crack, so
        // it lies wholly inside the sheet or wholly outside); five points, so that a
        // centre on an edge shared inside the sheet is not lost.
        bool inside = robustInside(c, m) || robustInside(c + vec2(0.25, 0.25), m) ||
                      robustInside(c + vec2(-0.25, 0.25), m) || robustInside(c + vec2(0.25, -0.25), m) ||
                      robustInside(c + vec2(-0.25, -0.25), m);
        oValue = vec4(zhi, inside ? 1.0 : 0.0, 0.0, 0.0);
    } else if (kMode == 1) {
        float h = 0.5 + fMisc.x;
        if (!overlaps(c, h, m)) discard;
        float zlo, zhi;
        depthBounds(c, h + m, zlo, zhi);
        oValue = vec4(zhi, 0.0, 0.0, 0.0);
    } else {
        oValue = vec4(0.0);
        if (!overlaps(c, 0.5, m)) return;
        float zlo, zhi;
        depthBounds(c, 0.5 + m, zlo, zhi);
        ivec2 pix = ivec2(c);
        float occ = texelFetch(uOcc, pix, 0).r;
        float rec = texelFetch(uRecv, pix, 0).r;
        bool lit = zlo <= occ;
        bool behind = uAnyReceiver || rec > zlo + uBias;
        if (kMode == 2 && lit) atomicAdd(counts[2u * fId], 1u);
        if (lit && behind) {
            if (kMode == 2) {
                atomicAdd(counts[2u * fId + 1u], 1u);
                passedPiece[fPiece] = 1u;
            }
            if (recorded(pix)) {
                uint k = atomicAdd(slots[fId].w, 1u);
                if (k < slots[fId].z)
                    records[fId * uRecordCap + slots[fId].y + k] = uvec4(uint(pix.x), uint(pix.y), floatBitsToUint(zlo), uView);
            }
        }
    }
}
)";

std::string confirmRasterFs(int pass) {
    std::string source = kConfirmRasterFs;
    source.insert(source.find('\n') + 1, "#define PASS_MODE " + std::to_string(pass) + "\n");  // after #version
    return source;
}

// The sheets' pixel rectangles, as two triangles each (pixel coordinates).
const char* const kConfirmRectVs = R"(#version 430 core
layout(location = 0) in vec2 aPix;
uniform vec2 uSize;
void main() { gl_Position = vec4(aPix / uSize * 2.0 - 1.0, 0.0, 1.0); }
)";

// A sheet's pixel counts when a point of it was robustly inside and no crack touched it.
const char* const kConfirmResolveFs = R"(#version 430 core
layout(binding = 0) uniform sampler2D uWork;
layout(location = 0) out vec4 oValue;
void main() {
    vec2 v = texelFetch(uWork, ivec2(gl_FragCoord.xy), 0).rg;
    if (v.g < 0.5 || v.r >= 1e29) discard;
    oValue = vec4(v.r, 0.0, 0.0, 1.0);
}
)";

// Resets the work buffer where a batch drew (no blending).
const char* const kConfirmClearFs = R"(#version 430 core
layout(location = 0) out vec4 oValue;
void main() { oValue = vec4(-1e30, 0.0, 0.0, 0.0); }
)";

}  // namespace shadowcull::gpu
