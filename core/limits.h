// Accepted magnitudes of the numbers a space may hold (docs/format.md, "Accepted ranges").
//
// Why bounds at all: the stages compute in a window-local frame, in doubles for the exact
// tests and in floats for Embree and OpenGL. A finite but huge number (a transform entry of
// 7e9, a vertex at 2e18, a chunk of 1e20 m) overflows those floats (Embree asserts), turns
// into inf or NaN inside CGAL (GMP traps) or makes a grid of 1e300 cells. Every number is
// therefore checked where it is read, and the error names the file and line. Within these
// bounds a placed coordinate stays within 1e5 m of its chunk origin, where a float still
// resolves 8 mm, and no product in the stages overflows a double.
#pragma once

namespace shadowcull::limits {

// Metres. Mesh vertices (model space, after glTF node transforms), transform translations,
// and every placed vertex relative to its chunk origin.
constexpr double kMaxLocalCoordinate = 1e5;
// A transform's 3x3 part: each entry (a scale of up to 10,000; a singular or nearly
// singular matrix is refused separately by its determinant).
constexpr double kMaxLinearEntry = 1e4;
// The inverse of a transform's 3x3 part: each entry (a model unit no shorter than 1e-10 m in
// any direction). Embree and OpenGL invert the placement in floats: with window-local
// coordinates up to ~1e5 m the ray in model space stays below 1e15, inside Embree's valid
// range (1.8e18), and an entry below float's normal range (a scale of 1e-45) is never
// flushed to zero, which would make the float copy singular.
constexpr double kMaxInverseEntry = 1e10;
// Metres: the side of a chunk.
constexpr double kMinChunkSize = 1.0;
constexpr double kMaxChunkSize = 1e5;
// Metres: light range, bias, slope bias, filter radius, terrain tolerance and the heights
// of a terrain.
constexpr double kMaxLength = 1e5;
// Metres: light positions are world coordinates; the chunk grid (16-bit indices times
// kMaxChunkSize) spans 3.3e9 m.
constexpr double kMaxWorldCoordinate = 1e10;
// Chunks on each side of the window of bake --method gpu (space.xml <neighbours>).
constexpr int kMaxNeighbours = 64;

}  // namespace shadowcull::limits
