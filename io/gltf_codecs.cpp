#include "io/gltf_codecs.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>

#include <draco/compression/decode.h>
#include <meshoptimizer.h>

namespace shadowcull::gltf_codecs {

// Little-endian reads that do not depend on host byte order or alignment.
uint32_t readUint(const uint8_t* p, size_t bytes) {
    uint32_t v = 0;
    for (size_t k = 0; k < bytes; ++k) v |= uint32_t(p[k]) << (8 * k);
    return v;
}

float readFloat(const uint8_t* p) {
    uint32_t u = readUint(p, 4);
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}

bool decodeBase64(std::string_view s, std::vector<uint8_t>& out) {
    uint32_t acc = 0;
    int bits = 0;
    size_t k = 0;
    for (; k < s.size() && s[k] != '='; ++k) {
        const char c = s[k];
        int v = c >= 'A' && c <= 'Z' ? c - 'A' : c >= 'a' && c <= 'z' ? c - 'a' + 26 : c >= '0' && c <= '9' ? c - '0' + 52
              : c == '+' ? 62 : c == '/' ? 63 : -1;
        if (v < 0) return false;
        acc = ((acc << 6) | uint32_t(v)) & 0xffffff;
        if ((bits += 6) >= 8) out.push_back(uint8_t(acc >> (bits -= 8)));
    }
    return s.find_first_not_of('=', k) == std::string_view::npos;
}

std::string percentDecode(const std::string& s) {
    std::string out;
    for (size_t k = 0; k < s.size(); ++k) {
        if (s[k] == '%' && k + 2 < s.size() && std::isxdigit((unsigned char)s[k + 1]) && std::isxdigit((unsigned char)s[k + 2])) {
            out += char(std::stoi(s.substr(k + 1, 2), nullptr, 16));
            k += 2;
        } else {
            out += s[k];
        }
    }
    return out;
}

size_t componentSize(uint64_t componentType) {
    return componentType == 5120 || componentType == 5121 ? 1
         : componentType == 5122 || componentType == 5123 ? 2
         : componentType == 5125 || componentType == 5126 ? 4 : 0;
}

// One component as a number. Integer types (KHR_mesh_quantization) are taken as they are,
// or when normalized by the glTF 2.0 formulas: signed max(c / (2^(n-1) - 1), -1.0),
// unsigned c / (2^n - 1).
double component(const uint8_t* p, uint64_t componentType, bool normalized) {
    switch (componentType) {
    case 5120: {
        const double c = double(int(p[0]) - (p[0] >= 0x80 ? 0x100 : 0));
        return normalized ? std::max(c / 127.0, -1.0) : c;
    }
    case 5121: return normalized ? p[0] / 255.0 : double(p[0]);
    case 5122: {
        const uint32_t u = readUint(p, 2);
        const double c = double(long(u) - (u >= 0x8000 ? 0x10000 : 0));
        return normalized ? std::max(c / 32767.0, -1.0) : c;
    }
    case 5123: return normalized ? readUint(p, 2) / 65535.0 : double(readUint(p, 2));
    case 5125: return double(readUint(p, 4));
    default: return double(readFloat(p));
    }
}

int decodeMeshopt(const std::string& mode, const std::string& filter, uint64_t count, uint64_t stride,
                  const uint8_t* src, size_t length, std::vector<uint8_t>& out) {
    out.assign(size_t(count * stride), 0);
    const int rc = mode == "ATTRIBUTES" ? meshopt_decodeVertexBuffer(out.data(), count, stride, src, length)
                 : mode == "TRIANGLES"  ? meshopt_decodeIndexBuffer(out.data(), count, stride, src, length)
                                        : meshopt_decodeIndexSequence(out.data(), count, stride, src, length);
    if (rc != 0) return rc;
    if (filter == "OCTAHEDRAL") meshopt_decodeFilterOct(out.data(), count, stride);
    if (filter == "QUATERNION") meshopt_decodeFilterQuat(out.data(), count, stride);
    if (filter == "EXPONENTIAL") meshopt_decodeFilterExp(out.data(), count, stride);
    return 0;
}

Expected<DracoMesh> decodeDraco(const uint8_t* data, size_t length, uint64_t id, uint64_t maxElements) {
    auto bad = [](const std::string& what) { return makeError(ErrorKind::BadInput, "", 0, what); };
    std::unique_ptr<draco::Mesh> mesh;
    try {
        draco::DecoderBuffer buffer;
        buffer.Init(reinterpret_cast<const char*>(data), length);
        draco::Decoder decoder;
        draco::StatusOr<std::unique_ptr<draco::Mesh>> decoded = decoder.DecodeMeshFromBuffer(&buffer);
        if (!decoded.ok()) return bad("does not decode (" + decoded.status().error_msg_string() + ")");
        mesh = std::move(decoded).value();
    } catch (const std::bad_alloc&) {
        return bad("does not decode (out of memory; corrupt?)");
    } catch (const std::length_error&) {
        return bad("does not decode (corrupt sizes)");
    }
    if (!mesh) return bad("holds no mesh");
    const draco::PointAttribute* attribute = id <= UINT32_MAX ? mesh->GetAttributeByUniqueId(uint32_t(id)) : nullptr;
    if (!attribute) return bad("has no attribute with unique id " + std::to_string(id) + " (attributes.POSITION)");
    if (attribute->num_components() != 3)
        return bad("has " + std::to_string(attribute->num_components()) + " components in its POSITION attribute (3 expected)");
    const uint64_t points = mesh->num_points(), faces = mesh->num_faces();
    if (points + 3 * faces > maxElements)
        return bad("decodes to " + std::to_string(points) + " points and " + std::to_string(faces) +
                   " triangles, more than 64 elements per byte of the file and buffers");
    // Value indices and the value buffer are checked before anything is read through them.
    const int64_t valueBytes = int64_t(attribute->size()) * attribute->byte_stride();
    if (!attribute->buffer() || attribute->byte_offset() < 0 ||
        attribute->byte_stride() < int64_t(3 * draco::DataTypeLength(attribute->data_type())) ||
        attribute->byte_offset() + valueBytes > int64_t(attribute->buffer()->data_size()) ||
        (!attribute->is_mapping_identity() && attribute->indices_map_size() < points))
        return bad("is inconsistent (attribute storage)");
    DracoMesh out;
    out.positions.resize(size_t(points));
    for (uint32_t k = 0; k < points; ++k) {
        const draco::AttributeValueIndex value = attribute->mapped_index(draco::PointIndex(k));
        float p[3];
        if (value.value() >= attribute->size() || !attribute->ConvertValue<float, 3>(value, p))
            return bad("is inconsistent (point " + std::to_string(k) + ")");
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
            return bad("has a POSITION that is not finite (point " + std::to_string(k) + ")");
        out.positions[k] = glm::dvec3(p[0], p[1], p[2]);
    }
    out.triangles.reserve(size_t(faces));
    for (uint32_t f = 0; f < faces; ++f) {
        const draco::Mesh::Face& face = mesh->face(draco::FaceIndex(f));
        std::array<uint32_t, 3> t{face[0].value(), face[1].value(), face[2].value()};
        for (uint32_t c : t)
            if (c >= points)
                return bad("names point " + std::to_string(c) + " of " + std::to_string(points) + " in triangle " +
                           std::to_string(f));
        out.triangles.push_back(t);
    }
    return out;
}

}  // namespace shadowcull::gltf_codecs
