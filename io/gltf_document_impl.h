// The glTF document reader's private parts, shared by its two halves: io/gltf_document.cpp
// (the public class, the container, buffers, buffer views and accessors) and
// io/gltf_meshes.cpp (nodes, scenes, meshes, materials and primitive decoding). Included
// by those two files only.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/gltf_document.h"
#include "util/status.h"

namespace shadowcull {
namespace gltf_detail {

// Thrown only inside the reader and turned into an Error by the public methods: validation
// is deeply nested and an exception keeps each check to one line.
struct GltfFailure {
    ErrorKind kind;
    int line;
    std::string message;
};

[[noreturn]] inline void fail(std::string message, ErrorKind kind = ErrorKind::BadInput, int line = 0) {
    throw GltfFailure{kind, line, std::move(message)};
}

inline std::string at(const std::string& array, size_t i) { return gltfPath(array, i); }

inline const nlohmann::json* member(const nlohmann::json& obj, const char* key) {
    auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
}

inline uint64_t uintField(const nlohmann::json& obj, const char* key, const std::string& where,
                          std::optional<uint64_t> def = {}) {
    const nlohmann::json* v = member(obj, key);
    if (!v) {
        if (!def) fail(where + ": '" + key + "' is missing");
        return *def;
    }
    if (!v->is_number_unsigned()) fail(where + "." + key + ": non-negative integer expected");
    return v->get<uint64_t>();
}

// An accessor resolved to bytes; `data` is null for an accessor without bufferView, whose
// elements are all zero by the glTF spec. `data` points into a buffer, into a decoded
// EXT_meshopt_compression view (both owned by the document), or into `owned` (a sparse
// accessor, applied to a copy of its base).
struct AccessorView {
    std::string where;
    uint64_t componentType = 0;
    bool normalized = false;
    std::string type;
    size_t count = 0;
    size_t stride = 0;
    const uint8_t* data = nullptr;
    std::shared_ptr<const std::vector<uint8_t>> owned;
};

// A buffer view's bytes: a range of its buffer, or what its EXT_meshopt_compression data
// decodes to. `stride` is the view's byteStride when it has one.
struct ViewBytes {
    const uint8_t* data = nullptr;
    uint64_t length = 0;
    std::optional<uint64_t> stride;
    std::string origin;        // for messages: "buffers[0]", or "the data decoded from ..."
    uint64_t originOffset = 0;  // the view's byteOffset in `origin`
    std::string describe(uint64_t offset) const {
        return "byte offset " + std::to_string(originOffset + offset) + " of " + origin;
    }
};

}  // namespace gltf_detail

struct GltfDocument::Impl {
    using json = nlohmann::json;  // the enclosing class has a member function named json
    using AccessorView = gltf_detail::AccessorView;
    using ViewBytes = gltf_detail::ViewBytes;

    std::string path;
    json doc;
    bool isGlb = false;
    std::optional<std::vector<uint8_t>> bin;
    std::vector<std::optional<std::vector<uint8_t>>> buffers;
    std::vector<GltfNode> nodes;
    std::vector<std::optional<std::vector<GltfPrimitive>>> meshes;  // decoded on first use
    std::vector<std::string> sourceFiles;
    std::vector<Diagnostic> warnings;
    // EXT_meshopt_compression views by index, decoded on first use (map: stable references).
    std::map<uint64_t, std::vector<uint8_t>> decodedViews;
    uint64_t bufferBytes = 0;   // bytes of the buffers read so far
    uint64_t decodedBytes = 0;  // bytes of decodedViews
    uint64_t fileBytes = 0;     // bytes of the .gltf/.glb itself
    // Vertices and indices decoded so far, over every primitive. Each primitive decodes its
    // accessors anew, so a small file whose thousand primitives all name one big accessor
    // (or one of 2^24 zeros without bufferView) would otherwise ask for a copy each:
    // hundreds of gigabytes from kilobytes. A real file decodes at most about 64 elements
    // per byte it holds (meshopt's best ratio; a byte per index), so more than that is
    // refused as corrupt or hostile.
    uint64_t decodedElements = 0;
    uint64_t elementBudget() const { return 64 * (fileBytes + bufferBytes) + (uint64_t(1) << 24); }
    void spend(uint64_t elements, const std::string& where);

    // The document: container, JSON and required extensions (io/gltf_document.cpp).
    void open();
    void checkRequiredExtensions() const;
    bool declares(const char* name) const;
    const json& array(const char* name) const;
    const json& element(const char* name, uint64_t i, const std::string& referrer) const;
    void readContainer();
    void readGlb(const std::vector<uint8_t>& bytes, std::string& text);

    // Buffers, buffer views and accessors (io/gltf_document.cpp).
    const std::vector<uint8_t>& buffer(uint64_t i, const std::string& referrer);
    ViewBytes bufferView(uint64_t view, const std::string& referrer);
    const std::vector<uint8_t>& meshoptView(uint64_t view, const json& bv, const json& ext, const std::string& where,
                                            uint64_t viewLength);
    AccessorView accessor(uint64_t i, const std::string& referrer);
    void applySparse(const json& sparse, AccessorView& v, size_t elementSize);
    const uint8_t* sparseData(const json& part, const std::string& where, uint64_t n, size_t size);

    // Nodes and scenes (io/gltf_meshes.cpp).
    void readNodes();
    void readNode(const json& list, size_t n);
    void linkChildren();
    void checkAcyclic() const;
    std::vector<size_t> sceneRoots(std::optional<size_t> sceneIndex) const;

    // Meshes, materials and primitives (io/gltf_meshes.cpp).
    const json& primitives(size_t m) const;
    std::vector<PrimitiveGroup> groups(size_t m) const;
    const std::vector<GltfPrimitive>& mesh(size_t m, const std::string& referrer);
    void readMaterial(const json& prim, const std::string& primWhere, PrimitiveGroup& g) const;
    void decodePrimitive(const json& prim, const std::string& where, GltfPrimitive& out);
    AccessorView decodePositions(const json& attributes, const std::string& where, GltfPrimitive& out);
    std::vector<uint32_t> decodeIndices(const json& prim, const std::string& where, const AccessorView& pos);
    void decodeDraco(const json& prim, const json& ext, const json& attributes, const std::string& where, uint64_t mode,
                     GltfPrimitive& out);
};

}  // namespace shadowcull
