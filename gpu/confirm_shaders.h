// GLSL of the conservative confirmation passes (gpu/confirm_stage.cpp says what each pass
// proves and why the margins only ever admit more).
#pragma once

#include <string>

namespace shadowcull::gpu {

// One instance per RasterPiece (gpu/conservative.h): the four corners of its cover.
extern const char* const kConfirmRasterVs;
// Pass 0 occluder sheet (work buffer), 1 receivers, 2 caster query (count and record),
// 3 record only: one program per pass, the source after "#define PASS_MODE <pass>"
// (confirmRasterFs).
extern const char* const kConfirmRasterFs;
std::string confirmRasterFs(int pass);
// Pixel rectangles (two triangles each), pixel coordinates.
extern const char* const kConfirmRectVs;
// A sheet's pixel counts when a point of it was robustly inside and no crack touched it.
extern const char* const kConfirmResolveFs;
// Resets the work buffer where a batch drew.
extern const char* const kConfirmClearFs;

}  // namespace shadowcull::gpu
