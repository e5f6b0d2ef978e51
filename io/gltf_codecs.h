// Byte-level decoding for glTF (io/gltf_document.cpp, io/gltf_meshes.cpp): little-endian
// reads, accessor components (with KHR_mesh_quantization's normalisation), base64 and
// percent-encoding, and the two compression libraries (libmeshoptimizer for
// EXT_meshopt_compression, libdraco for KHR_draco_mesh_compression). The document layer
// checks every size and field before calling these; they only check what the decoders
// themselves produce.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "util/status.h"

namespace shadowcull::gltf_codecs {

uint32_t readUint(const uint8_t* p, size_t bytes);  // little-endian, any alignment
float readFloat(const uint8_t* p);
size_t componentSize(uint64_t componentType);  // 0 for an unknown type
// One component as a number: integer types as they are, or normalized by the glTF 2.0
// formulas (signed max(c / (2^(n-1) - 1), -1), unsigned c / (2^n - 1)); FLOAT otherwise.
double component(const uint8_t* p, uint64_t componentType, bool normalized);
bool decodeBase64(std::string_view s, std::vector<uint8_t>& out);
std::string percentDecode(const std::string& s);

// EXT_meshopt_compression: `count` elements of `stride` bytes decoded from `length` bytes
// at `src` into `out`, then the filter applied. Arguments must already satisfy the
// extension's rules (mode ATTRIBUTES/TRIANGLES/INDICES, stride, filter). Returns
// meshoptimizer's code: 0 on success.
int decodeMeshopt(const std::string& mode, const std::string& filter, uint64_t count, uint64_t stride,
                  const uint8_t* src, size_t length, std::vector<uint8_t>& out);

// KHR_draco_mesh_compression: positions (attribute `positionId`) and faces of the Draco
// mesh in `data`. The decoder's output is trusted no further than needed: storage, value
// indices and face indices are checked. More than `maxElements` points + 3 x faces is an
// error before anything is copied. Error messages continue "the Draco data of <view> ...".
struct DracoMesh {
    std::vector<glm::dvec3> positions;
    std::vector<std::array<uint32_t, 3>> triangles;
};
Expected<DracoMesh> decodeDraco(const uint8_t* data, size_t length, uint64_t positionId, uint64_t maxElements);

}  // namespace shadowcull::gltf_codecs
