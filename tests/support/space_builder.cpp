// Writes spaces in the scene format (shared/spec/scene-format.md); see space_builder.h.

#include "tests/support/space_builder.h"

#include <png.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace shadowcull::testing {

namespace fs = std::filesystem;

// =======================================================================================
// Transforms

Affine Affine::translation(const glm::dvec3& t) {
    Affine a;
    a.row3 = t;
    return a;
}

Affine Affine::scaling(const glm::dvec3& s) {
    Affine a;
    a.row0 = {s.x, 0, 0};
    a.row1 = {0, s.y, 0};
    a.row2 = {0, 0, s.z};
    return a;
}

Affine Affine::rotationY(double degrees) {
    double c, s;
    const double quarters = degrees / 90.0;
    if (quarters == std::floor(quarters) && std::abs(quarters) < 1e9) {
        // Exact table, so that quarter turns compose without rounding residue.
        const int k = ((int(quarters) % 4) + 4) % 4;
        const double cs[4] = {1, 0, -1, 0}, sn[4] = {0, 1, 0, -1};
        c = cs[k];
        s = sn[k];
    } else {
        const double r = degrees * 3.14159265358979323846 / 180.0;
        c = std::cos(r);
        s = std::sin(r);
    }
    // Rows are the images of the local axes: x -> (c, 0, -s), z -> (s, 0, c).
    Affine a;
    a.row0 = {c, 0, -s};
    a.row2 = {s, 0, c};
    return a;
}

Affine Affine::then(const Affine& next) const {
    Affine a;
    a.row0 = next.applyLinear(row0);
    a.row1 = next.applyLinear(row1);
    a.row2 = next.applyLinear(row2);
    a.row3 = next.apply(row3);
    return a;
}

Affine WorldTransform::affine() const {
    return Affine::rotationY(90.0 * turns()).then(Affine::translation(translation));
}

namespace {

// One quarter turn of a vector (x' = z, z' = -x): a signed permutation, hence exact.
glm::dvec3 turnVector(glm::dvec3 v, int turns) {
    for (int k = 0; k < turns; ++k) v = glm::dvec3(v.z, v.y, -v.x);
    return v;
}

// A world coordinate split into chunk index and offset within the chunk, l in [0, S).
struct AxisSplit {
    int g = 0;
    double l = 0.0;
};

AxisSplit splitAxis(double v, double S) {
    if (!std::isfinite(v) || std::abs(v / S) > 1e9)
        throw std::invalid_argument("space builder: coordinate " + formatNumber(v) + " is not usable for chunking");
    double g = std::floor(v / S);
    double l = v - g * S;
    if (l < 0) { g -= 1; l += S; }  // v/S rounded up across a chunk boundary
    if (l >= S) { g += 1; l -= S; }
    return {int(g), l};
}

// The split of -v given the split of v (x' = -x under a half or quarter turn). Only one
// rounding (S - l) and none when v lies on a chunk boundary.
AxisSplit negateAxis(AxisSplit a, double S) {
    return a.l == 0.0 ? AxisSplit{-a.g, 0.0} : AxisSplit{-a.g - 1, S - a.l};
}

// The whole-chunk shift of a chunk-aligned translation.
std::pair<int, int> chunkShift(const WorldTransform& wt, double S) {
    auto whole = [&](double t, const char* axis) {
        const double n = std::round(t / S);
        if (!std::isfinite(t) || n * S != t || std::abs(n) > 65536)
            throw std::invalid_argument(std::string("space builder: WorldTransform translation.") + axis + " = " +
                                        formatNumber(t) + " is not a whole number of chunks of " + formatNumber(S) +
                                        " m");
        return int(n);
    };
    return {whole(wt.translation.x, "x"), whole(wt.translation.z, "z")};
}

void checkChunkRange(ChunkId c) {
    if (c.gx < -32768 || c.gx > 32767 || c.gz < -32768 || c.gz > 32767)
        throw std::out_of_range("space builder: chunk (" + std::to_string(c.gx) + ", " + std::to_string(c.gz) +
                                 ") does not fit a 16-bit chunk name");
}

std::string escapeXml(const std::string& s) {
    std::string out;
    for (char ch : s) {
        if (ch == '&') out += "&amp;";
        else if (ch == '<') out += "&lt;";
        else if (ch == '>') out += "&gt;";
        else out += ch;
    }
    return out;
}

std::string vec3Text(const glm::dvec3& v) {
    return formatNumber(v.x) + " " + formatNumber(v.y) + " " + formatNumber(v.z);
}

void writeTextFile(const fs::path& p, const std::string& text) {
    fs::create_directories(p.parent_path());
    std::ofstream out(p, std::ios::binary);
    out << text;
    out.close();
    if (!out) throw std::runtime_error("space builder: cannot write " + p.string());
}

// A grey PNG of `depth` 8 or 16 bits; samples row-major, row 0 first.
void writeGreyPng(const fs::path& p, int w, int h, int depth, const std::vector<uint16_t>& samples) {
    fs::create_directories(p.parent_path());
    std::FILE* f = std::fopen(p.string().c_str(), "wb");
    if (!f) throw std::runtime_error("space builder: cannot create " + p.string());
    std::vector<png_byte> rows(size_t(w) * size_t(h) * size_t(depth / 8));
    for (size_t k = 0; k < samples.size(); ++k) {
        if (depth == 16) {  // PNG stores 16-bit samples big-endian
            rows[2 * k] = png_byte(samples[k] >> 8);
            rows[2 * k + 1] = png_byte(samples[k] & 0xff);
        } else {
            rows[k] = png_byte(samples[k]);
        }
    }
    std::vector<png_bytep> rowPointers(static_cast<size_t>(h));
    for (int j = 0; j < h; ++j) rowPointers[size_t(j)] = rows.data() + size_t(j) * size_t(w) * size_t(depth / 8);

    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    auto fail = [&]() {
        png_destroy_write_struct(png ? &png : nullptr, info ? &info : nullptr);
        std::fclose(f);
        throw std::runtime_error("space builder: cannot write PNG " + p.string());
    };
    if (!png || !info) fail();
    if (setjmp(png_jmpbuf(png)) != 0) fail();  // libpng reports errors by longjmp to here
    png_init_io(png, f);
    png_set_IHDR(png, info, png_uint_32(w), png_uint_32(h), depth, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_rows(png, info, rowPointers.data());
    png_write_png(png, info, PNG_TRANSFORM_IDENTITY, nullptr);
    png_destroy_write_struct(&png, &info);
    if (std::fclose(f) != 0) throw std::runtime_error("space builder: cannot write PNG " + p.string());
}

}  // namespace

// =======================================================================================
// Chunk grid and small helpers

std::string chunkBaseName(int gx, int gz) {
    checkChunkRange({gx, gz});
    char buf[16];
    std::snprintf(buf, sizeof buf, "%04x%04x", unsigned(uint16_t(int16_t(gx))), unsigned(uint16_t(int16_t(gz))));
    return buf;
}

std::string chunkName(int gx, int gz) { return chunkBaseName(gx, gz) + "o.chunk"; }

ChunkId chunkContaining(double x, double z, double chunkSize) {
    return {splitAxis(x, chunkSize).g, splitAxis(z, chunkSize).g};
}

ChunkId mapChunk(ChunkId c, const WorldTransform& wt, double chunkSize) {
    // One turn takes the square [gx, gx+1) x [gz, gz+1) to [gz, gz+1) x (-gx-1, -gx].
    for (int k = 0; k < wt.turns(); ++k) c = {c.gz, -c.gx - 1};
    const auto [dx, dz] = chunkShift(wt, chunkSize);
    return {c.gx + dx, c.gz + dz};
}

uint16_t quantiseHeight(double h, double minHeight, double maxHeight) {
    if (!std::isfinite(h) || !(maxHeight > minHeight))
        throw std::range_error("space builder: height " + formatNumber(h) + " or range [" + formatNumber(minHeight) +
                               ", " + formatNumber(maxHeight) + "] is not usable");
    const double q = (h - minHeight) / (maxHeight - minHeight) * 65535.0;
    // Half a step of slack, so that heights computed with rounding still land on 0 or 65535.
    if (q < -0.5 || q > 65535.5)
        throw std::range_error("space builder: height " + formatNumber(h) + " m is outside [" +
                               formatNumber(minHeight) + ", " + formatNumber(maxHeight) + "]");
    return uint16_t(std::clamp(std::llround(q), 0LL, 65535LL));
}

double dequantiseHeight(uint16_t sample, double minHeight, double maxHeight) {
    return minHeight + double(sample) * ((maxHeight - minHeight) / 65535.0);
}

std::string formatNumber(double v) {
    if (v == 0.0) v = 0.0;  // no "-0" in files
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest round-trip form
    return std::string(buf, r.ptr);
}

std::string fixedUuid(uint32_t n) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "00000000-00000000-00000000-%08X", unsigned(n));
    return buf;
}

uint64_t DeterministicRng::next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

double DeterministicRng::uniform(double lo, double hi) {
    return lo + (hi - lo) * (double(next() >> 11) * (1.0 / 9007199254740992.0));  // 53-bit fraction
}

int DeterministicRng::below(int n) { return int(next() % uint64_t(n)); }

// =======================================================================================
// Meshes

GroupSpec GroupSpec::named(std::string material, bool alphaTested) {
    GroupSpec g;
    g.material = std::move(material);
    g.alphaTested = alphaTested;
    return g;
}

int MeshSpec::addGroup(const GroupSpec& g) {
    groups.push_back(g);
    return int(groups.size()) - 1;
}

int MeshSpec::addVertex(const glm::dvec3& p) {
    positions.push_back(p);
    return int(positions.size()) - 1;
}

void MeshSpec::addTriangle(int a, int b, int c, int group) {
    triangles.push_back({a, b, c});
    triangleGroup.push_back(group);
}

void MeshSpec::addFace(const std::vector<glm::dvec3>& polygon, int group, const glm::dvec3& inside) {
    // Newell normal of the polygon as given; reverse when it points towards `inside`.
    glm::dvec3 n(0.0);
    for (size_t k = 0; k < polygon.size(); ++k) {
        const glm::dvec3& a = polygon[k];
        const glm::dvec3& b = polygon[(k + 1) % polygon.size()];
        n += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    const glm::dvec3 away = polygon[0] - inside;
    const bool flip = n.x * away.x + n.y * away.y + n.z * away.z < 0;
    std::vector<int> idx;
    for (const glm::dvec3& p : polygon) idx.push_back(addVertex(p));
    if (flip) std::reverse(idx.begin(), idx.end());
    for (size_t k = 1; k + 1 < idx.size(); ++k) addTriangle(idx[0], idx[k], idx[k + 1], group);
}

MeshSpec& MeshSpec::append(const MeshSpec& other) {
    const int v0 = int(positions.size()), g0 = int(groups.size());
    positions.insert(positions.end(), other.positions.begin(), other.positions.end());
    groups.insert(groups.end(), other.groups.begin(), other.groups.end());
    for (size_t t = 0; t < other.triangles.size(); ++t) {
        const auto& tri = other.triangles[t];
        addTriangle(tri[0] + v0, tri[1] + v0, tri[2] + v0, other.triangleGroup[t] + g0);
    }
    return *this;
}

MeshSpec MeshSpec::welded() const {
    MeshSpec out;
    out.groups = groups;
    std::map<std::array<double, 3>, int> seen;
    std::vector<int> remap(positions.size());
    for (size_t v = 0; v < positions.size(); ++v) {
        const std::array<double, 3> key{positions[v].x, positions[v].y, positions[v].z};
        auto it = seen.find(key);
        remap[v] = it != seen.end() ? it->second : (seen[key] = out.addVertex(positions[v]));
    }
    for (size_t t = 0; t < triangles.size(); ++t)
        out.addTriangle(remap[size_t(triangles[t][0])], remap[size_t(triangles[t][1])], remap[size_t(triangles[t][2])],
                        triangleGroup[t]);
    return out;
}

namespace {

// The six faces of an axis-aligned box, minus the top when `withTop` is false.
MeshSpec boxFaces(const glm::dvec3& lo, const glm::dvec3& hi, const GroupSpec& g, bool withTop) {
    if (!(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z)) throw std::invalid_argument("space builder: box needs min < max");
    MeshSpec m;
    const int group = m.addGroup(g);
    auto corner = [&](int bits) {
        return glm::dvec3(bits & 1 ? hi.x : lo.x, bits & 2 ? hi.y : lo.y, bits & 4 ? hi.z : lo.z);
    };
    const glm::dvec3 centre = (lo + hi) * 0.5;
    // Each face: the axis it is normal to, and which side; corners listed around the face.
    for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {
            if (axis == 1 && side == 1 && !withTop) continue;
            const int a = 1 << ((axis + 1) % 3), b = 1 << ((axis + 2) % 3), s = side ? (1 << axis) : 0;
            m.addFace({corner(s), corner(s | a), corner(s | a | b), corner(s | b)}, group, centre);
        }
    }
    return m.welded();
}

}  // namespace

MeshSpec MeshSpec::box(const glm::dvec3& min, const glm::dvec3& max, const GroupSpec& g) {
    return boxFaces(min, max, g, true);
}

MeshSpec MeshSpec::openBox(const glm::dvec3& min, const glm::dvec3& max, const GroupSpec& g) {
    return boxFaces(min, max, g, false);
}

MeshSpec MeshSpec::quad(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& d,
                        const GroupSpec& g) {
    MeshSpec m;
    const int group = m.addGroup(g);
    const int ia = m.addVertex(a), ib = m.addVertex(b), ic = m.addVertex(c), id = m.addVertex(d);
    m.addTriangle(ia, ib, ic, group);
    m.addTriangle(ia, ic, id, group);
    return m;
}

MeshSpec MeshSpec::rod(double length, double thickness, const GroupSpec& g) {
    const double h = thickness / 2;
    return box({0, -h, -h}, {length, h, h}, g);
}

MeshSpec MeshSpec::edgeSharingCubes(double size, const GroupSpec& g) {
    MeshSpec m = box({0, 0, 0}, {size, size, size}, g);
    MeshSpec second = box({size, size, 0}, {2 * size, 2 * size, size}, g);
    // Same material: fold the second cube's group into the first.
    const int v0 = int(m.positions.size());
    m.positions.insert(m.positions.end(), second.positions.begin(), second.positions.end());
    for (const auto& t : second.triangles) m.addTriangle(t[0] + v0, t[1] + v0, t[2] + v0, 0);
    return m.welded();
}

MeshSpec MeshSpec::jaggedSheet(int n, double cell, double zig, const GroupSpec& g) {
    MeshSpec m;
    const int group = m.addGroup(g);
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) m.addVertex({i * cell, ((i + j) % 2) * zig, j * cell});
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
            m.addTriangle(a, c, b, group);
            m.addTriangle(b, c, d, group);
        }
    return m;
}

void MeshSpec::addQuad(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& d, int group) {
    const int ia = addVertex(a), ib = addVertex(b), ic = addVertex(c), id = addVertex(d);
    addTriangle(ia, ib, ic, group);
    addTriangle(ia, ic, id, group);
}

// =======================================================================================
// Lights

LightSpec LightSpec::directional(std::string name, const glm::dvec3& direction) {
    LightSpec l;
    l.name = std::move(name);
    l.kind = LightKind::Directional;
    l.direction = direction;
    return l;
}

LightSpec LightSpec::point(std::string name, const glm::dvec3& position, double range) {
    LightSpec l;
    l.name = std::move(name);
    l.kind = LightKind::Point;
    l.position = position;
    l.range = range;
    return l;
}

LightSpec LightSpec::spot(std::string name, const glm::dvec3& position, const glm::dvec3& direction, double range,
                          double coneAngleDegrees) {
    LightSpec l = point(std::move(name), position, range);
    l.kind = LightKind::Spot;
    l.direction = direction;
    l.coneAngle = coneAngleDegrees;
    return l;
}

// =======================================================================================
// The builder: registering content

namespace {

// Material name of group g, as written to OBJ/MTL.
std::string materialName(const MeshSpec& m, size_t g) {
    return m.groups[g].material.empty() ? "group" + std::to_string(g) : m.groups[g].material;
}

// A mesh needs MTL materials unless it is a single plain group (then no `usemtl` at all:
// "a file with no usemtl is group 0").
bool needsMaterials(const MeshSpec& m) {
    return m.groups.size() > 1 || !m.groups[0].material.empty() || m.groups[0].alphaTested;
}

bool hasOverrides(const MeshSpec& m) {
    return std::any_of(m.groups.begin(), m.groups.end(), [](const GroupSpec& g) {
        return g.alphaTestOverride.has_value() || g.doubleSidedOverride.has_value();
    });
}

void validateMesh(const std::string& name, const MeshSpec& m) {
    auto fail = [&](const std::string& why) {
        throw std::invalid_argument("space builder: mesh " + name + ": " + why);
    };
    if (m.groups.empty()) fail("has no groups");
    if (m.triangleGroup.size() != m.triangles.size()) fail("triangleGroup and triangles differ in length");
    std::vector<bool> used(m.groups.size(), false);
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        for (int v : m.triangles[t])
            if (v < 0 || size_t(v) >= m.positions.size()) fail("triangle " + std::to_string(t) + " has a bad index");
        const int g = m.triangleGroup[t];
        if (g < 0 || size_t(g) >= m.groups.size()) fail("triangle " + std::to_string(t) + " has a bad group");
        used[size_t(g)] = true;
    }
    std::set<std::string> names;
    for (size_t g = 0; g < m.groups.size(); ++g) {
        // An OBJ group exists only through its triangles; an empty one would renumber the rest.
        if (!used[g]) fail("group " + std::to_string(g) + " has no triangles");
        if (!names.insert(materialName(m, g)).second) fail("material " + materialName(m, g) + " is used twice");
    }
}

}  // namespace

std::string SpaceBuilder::Mesh::resourcePath() const {
    return "models/" + name + (viaModelFile || hasOverrides(spec) ? ".model" : ".obj");
}

SpaceBuilder::SpaceBuilder(SpaceOptions options) : options_(std::move(options)) {}

std::string SpaceBuilder::addMesh(const std::string& name, const MeshSpec& mesh, bool viaModelFile) {
    if (name.empty() || name.find('/') != std::string::npos)
        throw std::invalid_argument("space builder: mesh name '" + name + "' must be non-empty without '/'");
    for (const Mesh& m : meshes_)
        if (m.name == name) throw std::invalid_argument("space builder: mesh " + name + " is added twice");
    validateMesh(name, mesh);
    meshes_.push_back({name, mesh, viaModelFile});
    return meshes_.back().resourcePath();
}

void SpaceBuilder::addFile(const std::string& relativePath, const std::string& contents) {
    files_.emplace_back(relativePath, contents);
}

std::string SpaceBuilder::addModel(const std::string& resource, const Affine& world, std::string uuid,
                                   std::optional<bool> castsShadow) {
    std::string path = resource;
    if (resource.find('/') == std::string::npos) {
        auto it = std::find_if(meshes_.begin(), meshes_.end(), [&](const Mesh& m) { return m.name == resource; });
        if (it == meshes_.end()) throw std::invalid_argument("space builder: no mesh named " + resource);
        path = it->resourcePath();
    }
    if (uuid.empty()) {
        // Deterministic but uuid-looking: a hash of a counter.
        DeterministicRng rng(0x5EEDull + uuidCounter_++);
        char buf[40];
        const uint64_t a = rng.next(), b = rng.next();
        std::snprintf(buf, sizeof buf, "%08X-%08X-%08X-%08X", unsigned(a >> 32), unsigned(a & 0xffffffffu),
                      unsigned(b >> 32), unsigned(b & 0xffffffffu));
        uuid = buf;
    }
    if (!uuids_.insert(uuid).second) throw std::invalid_argument("space builder: uuid " + uuid + " is used twice");
    placements_.push_back({path, uuid, world, castsShadow});
    return uuid;
}

void SpaceBuilder::addTerrain(int gx, int gz, int samples, HeightFunction height, double minHeight, double maxHeight) {
    checkChunkRange({gx, gz});
    if (samples < 2) throw std::invalid_argument("space builder: terrain needs N >= 2 samples per side");
    if (!(maxHeight > minHeight)) throw std::invalid_argument("space builder: terrain needs maxHeight > minHeight");
    if (!terrainIndex_.emplace(ChunkId{gx, gz}, terrains_.size()).second)
        throw std::invalid_argument("space builder: chunk " + chunkName(gx, gz) + " already has terrain");
    terrains_.push_back({{gx, gz}, samples, std::move(height), minHeight, maxHeight});
}

void SpaceBuilder::addFlatTerrain(int gx, int gz, double height, int samples) {
    // minHeight = height makes every sample 0, which reads back exactly as `height`; the
    // 1 m span is arbitrary (must only be > 0).
    addTerrain(gx, gz, samples, [height](double, double) { return height; }, height, height + 1.0);
}

void SpaceBuilder::addChunk(int gx, int gz) {
    checkChunkRange({gx, gz});
    forcedChunks_.push_back({gx, gz});
}

void SpaceBuilder::addChunkXml(int gx, int gz, const std::string& xml) {
    checkChunkRange({gx, gz});
    if (xml.find("<model") != std::string::npos || xml.find("<terrain") != std::string::npos)
        throw std::invalid_argument("space builder: chunk XML must not hold <model> or <terrain> "
                                    "(it would shift element indices)");
    chunkXml_.emplace_back(ChunkId{gx, gz}, xml);
}

int SpaceBuilder::addLight(const LightSpec& light) {
    lights_.push_back(light);
    return int(lights_.size());
}

void SpaceBuilder::expect(const std::string& key, int group, uint32_t mask, std::string why) {
    expectations_.push_back({key, group, mask, std::move(why)});
}

std::string SpaceBuilder::terrainKey(int gx, int gz) { return "terrain:" + chunkBaseName(gx, gz); }

// =======================================================================================
// The builder: terrain sampling

uint16_t SpaceBuilder::Terrain::code(int i, int j, double S) const {
    // Chunk-local offsets i*S/(N-1) are computed alone, so that the last sample lands on
    // exactly S and neighbouring chunks share their edge samples bit for bit.
    const double x = chunk.gx * S + double(i) * S / double(samples - 1);
    const double z = chunk.gz * S + double(j) * S / double(samples - 1);
    return quantiseHeight(height(x, z), minHeight, maxHeight);
}

std::vector<uint16_t> SpaceBuilder::Terrain::codes(double S) const {
    std::vector<uint16_t> out(size_t(samples) * size_t(samples));
    for (int j = 0; j < samples; ++j)
        for (int i = 0; i < samples; ++i) out[size_t(j) * size_t(samples) + size_t(i)] = code(i, j, S);
    return out;
}

std::optional<double> SpaceBuilder::terrainHeightAt(double x, double z) const {
    const double S = options_.chunkSize;
    const AxisSplit sx = splitAxis(x, S), sz = splitAxis(z, S);
    if (auto it = terrainIndex_.find({sx.g, sz.g}); it != terrainIndex_.end()) {
        const Terrain& t = terrains_[it->second];
        const double cell = S / double(t.samples - 1);
        const int i = std::min(int(sx.l / cell), t.samples - 2), j = std::min(int(sz.l / cell), t.samples - 2);
        const double u = sx.l / cell - i, v = sz.l / cell - j;
        auto h = [&](int di, int dj) { return dequantiseHeight(t.code(i + di, j + dj, S), t.minHeight, t.maxHeight); };
        // Cells split along the diagonal (i,j)-(i+1,j+1) (scene-format.md).
        if (u >= v) return h(0, 0) + u * (h(1, 0) - h(0, 0)) + v * (h(1, 1) - h(1, 0));
        return h(0, 0) + v * (h(0, 1) - h(0, 0)) + u * (h(1, 1) - h(0, 1));
    }
    return std::nullopt;
}

// =======================================================================================
// The builder: layout under a world transform

std::map<ChunkId, SpaceBuilder::ChunkLayout> SpaceBuilder::layout(const WorldTransform& wt) const {
    const double S = options_.chunkSize;
    const int turns = wt.turns();
    const auto [shiftX, shiftZ] = chunkShift(wt, S);
    std::map<ChunkId, ChunkLayout> out;
    auto chunkAt = [&](ChunkId c) -> ChunkLayout& {
        checkChunkRange(c);
        return out[c];
    };

    for (ChunkId c : forcedChunks_) chunkAt(mapChunk(c, wt, S));
    for (const auto& [c, xml] : chunkXml_) chunkAt(mapChunk(c, wt, S)).xml.push_back(xml);

    for (const Placement& p : placements_) {
        // Chunk and offset are split BEFORE moving, then moved as (index, offset) pairs:
        // a chunk-aligned translation changes only the index, so local x/z stay bit-identical.
        const AxisSplit x = splitAxis(p.world.row3.x, S), z = splitAxis(p.world.row3.z, S);
        AxisSplit nx = x, nz = z;
        if (turns == 1) { nx = z; nz = negateAxis(x, S); }         // x' = z,  z' = -x
        if (turns == 2) { nx = negateAxis(x, S); nz = negateAxis(z, S); }  // x' = -x, z' = -z
        if (turns == 3) { nx = negateAxis(z, S); nz = x; }         // x' = -z, z' = x
        Affine local;
        local.row0 = turnVector(p.world.row0, turns);
        local.row1 = turnVector(p.world.row1, turns);
        local.row2 = turnVector(p.world.row2, turns);
        local.row3 = glm::dvec3(nx.l, p.world.row3.y + wt.translation.y, nz.l);
        chunkAt({nx.g + shiftX, nz.g + shiftZ}).models.emplace_back(&p, local);
    }

    for (const Terrain& t : terrains_) chunkAt(mapChunk(t.chunk, wt, S)).terrain = &t;
    return out;
}

std::map<std::string, ObjectLocation> SpaceBuilder::locateObjects(const WorldTransform& wt) const {
    std::map<std::string, ObjectLocation> out;
    for (const auto& [id, chunk] : layout(wt)) {
        const std::string file = chunkName(id.gx, id.gz);
        int index = 0;  // written order: models, then terrain
        for (const auto& m : chunk.models) out[m.first->uuid] = {id, file, index++};
        if (chunk.terrain) out[terrainKey(chunk.terrain->chunk.gx, chunk.terrain->chunk.gz)] = {id, file, index};
    }
    return out;
}

std::vector<std::string> SpaceBuilder::chunkFiles(const WorldTransform& wt) const {
    std::vector<std::string> out;
    for (const auto& entry : layout(wt)) out.push_back(chunkName(entry.first.gx, entry.first.gz));
    return out;
}

// =======================================================================================
// The builder: writing

std::string SpaceBuilder::spaceXml(const WorldTransform& wt) const {
    std::ostringstream o;
    o << "<space>\n";
    o << "  <chunkSize> " << formatNumber(options_.chunkSize) << " </chunkSize>\n";
    // Neighbour counts are per grid direction, so they turn with the world: one turn takes
    // +x to -z (right -> bottom), +z to +x (top -> right), -x to +z, -z to -x.
    NeighbourSpec n = options_.neighbours;
    for (int k = 0; k < wt.turns(); ++k) n = {n.bottom, n.top, n.left, n.right};
    if (n.left == n.right && n.left == n.top && n.left == n.bottom)
        o << "  <neighbours> " << n.left << " </neighbours>\n";
    else
        o << "  <neighbours left=\"" << n.left << "\" right=\"" << n.right << "\" top=\"" << n.top << "\" bottom=\""
          << n.bottom << "\"/>\n";
    o << "  <terrainTolerance> " << formatNumber(options_.terrainTolerance) << " </terrainTolerance>\n";
    if (!options_.resourceRoot.empty())
        o << "  <resourceRoot> " << escapeXml(options_.resourceRoot) << " </resourceRoot>\n";
    const Affine move = wt.affine();
    for (const LightSpec& l : lights_) {
        static const char* const kinds[] = {"directional", "point", "spot"};
        o << "  <light>\n";
        o << "    <name> " << escapeXml(l.name) << " </name>\n";
        o << "    <type> " << kinds[int(l.kind)] << " </type>\n";
        if (l.kind != LightKind::Directional)
            o << "    <position> " << vec3Text(move.apply(l.position)) << " </position>\n";
        if (l.kind != LightKind::Point)
            o << "    <direction> " << vec3Text(move.applyLinear(l.direction)) << " </direction>\n";
        if (l.kind != LightKind::Directional) o << "    <range> " << formatNumber(l.range) << " </range>\n";
        if (l.kind == LightKind::Spot) o << "    <coneAngle> " << formatNumber(l.coneAngle) << " </coneAngle>\n";
        o << "    <bias> " << formatNumber(l.bias) << " </bias>\n";
        o << "    <slopeBias> " << formatNumber(l.slopeBias) << " </slopeBias>\n";
        o << "    <filterRadius> " << formatNumber(l.filterRadius) << " </filterRadius>\n";
        if (l.normalBias > 0) o << "    <normalBias> " << formatNumber(l.normalBias) << " </normalBias>\n";
        o << "  </light>\n";
    }
    o << "</space>\n";
    return o.str();
}

void SpaceBuilder::writeMesh(const std::string& resDir, const Mesh& m) const {
    const fs::path dir = fs::path(resDir) / "models";
    const MeshSpec& s = m.spec;
    const bool materials = needsMaterials(s);
    std::ostringstream obj;
    obj << "# " << m.name << ": " << s.groups.size() << " primitive group(s), metres\n";
    if (materials) obj << "mtllib " << m.name << ".mtl\n";
    for (const glm::dvec3& p : s.positions) obj << "v " << vec3Text(p) << "\n";
    // Groups are numbered by first `usemtl`, so faces go out group by group, in order.
    for (size_t g = 0; g < s.groups.size(); ++g) {
        if (materials) obj << "usemtl " << materialName(s, g) << "\n";
        for (size_t t = 0; t < s.triangles.size(); ++t) {
            const auto& tri = s.triangles[t];
            if (s.triangleGroup[t] != int(g)) continue;
            obj << "f " << tri[0] + 1 << " " << tri[1] + 1 << " " << tri[2] + 1 << "\n";  // OBJ counts from 1
        }
    }
    writeTextFile(dir / (m.name + ".obj"), obj.str());

    if (materials) {
        std::ostringstream mtl;
        bool anyAlpha = false;
        for (size_t g = 0; g < s.groups.size(); ++g) {
            mtl << "newmtl " << materialName(s, g) << "\nKd 0.6 0.6 0.6\n";
            if (s.groups[g].alphaTested) mtl << "map_d " << m.name << "_alpha.png\n";
            anyAlpha = anyAlpha || s.groups[g].alphaTested;
        }
        writeTextFile(dir / (m.name + ".mtl"), mtl.str());
        // The alpha mask itself: a 4 x 4 checker, so that the MTL names a real file.
        if (anyAlpha)
            writeGreyPng(dir / (m.name + "_alpha.png"), 4, 4, 8,
                         {255, 0, 255, 0, 0, 255, 0, 255, 255, 0, 255, 0, 0, 255, 0, 255});
    }

    if (m.viaModelFile || hasOverrides(s)) {
        std::ostringstream model;
        model << "<model>\n  <visual> " << m.name << ".obj </visual>\n";
        for (size_t g = 0; g < s.groups.size(); ++g) {
            const GroupSpec& gs = s.groups[g];
            if (!gs.alphaTestOverride && !gs.doubleSidedOverride) continue;
            model << "  <primitiveGroup index=\"" << g << "\"";
            if (gs.alphaTestOverride) model << " alphaTest=\"" << (*gs.alphaTestOverride ? "true" : "false") << "\"";
            if (gs.doubleSidedOverride)
                model << " doubleSided=\"" << (*gs.doubleSidedOverride ? "true" : "false") << "\"";
            model << "/>\n";
        }
        model << "</model>\n";
        writeTextFile(dir / (m.name + ".model"), model.str());
    }
}

void SpaceBuilder::write(const std::string& dir, const WorldTransform& wt) const {
    const fs::path root(dir);
    // A fresh directory only: stale chunk files from an earlier write would silently join
    // the space.
    if (fs::exists(root) && !(fs::is_directory(root) && fs::is_empty(root)))
        throw std::runtime_error("space builder: " + dir + " exists and is not an empty directory");
    // Everything that can be refused is worked out before the first file is written.
    const std::map<ChunkId, ChunkLayout> chunks = layout(wt);
    std::map<const Terrain*, std::vector<uint16_t>> terrainCodes;
    for (const Terrain& t : terrains_) terrainCodes[&t] = t.codes(options_.chunkSize);
    fs::create_directories(root);
    const fs::path res = options_.resourceRoot.empty() ? root : root / options_.resourceRoot;

    writeTextFile(root / "space.xml", spaceXml(wt));
    for (const Mesh& m : meshes_) writeMesh(res.string(), m);
    for (const auto& [path, contents] : files_) writeTextFile(res / path, contents);

    for (const auto& [id, chunk] : chunks) {
        std::ostringstream o;
        o << "<chunk>\n";
        for (const std::string& xml : chunk.xml) {
            std::istringstream lines(xml);
            for (std::string line; std::getline(lines, line);) o << "  " << line << "\n";
        }
        for (const auto& [p, local] : chunk.models) {
            o << "  <model>\n";
            o << "    <resource> " << escapeXml(p->resource) << " </resource>\n";
            o << "    <uuid> " << escapeXml(p->uuid) << " </uuid>\n";
            o << "    <transform>\n";
            o << "      <row0> " << vec3Text(local.row0) << " </row0>\n";
            o << "      <row1> " << vec3Text(local.row1) << " </row1>\n";
            o << "      <row2> " << vec3Text(local.row2) << " </row2>\n";
            o << "      <row3> " << vec3Text(local.row3) << " </row3>\n";
            o << "    </transform>\n";
            if (p->castsShadow)
                o << "    <castsShadow> " << (*p->castsShadow ? "true" : "false") << " </castsShadow>\n";
            o << "  </model>\n";
        }
        if (const Terrain* t = chunk.terrain) {
            const std::string base = chunkBaseName(id.gx, id.gz);
            o << "  <terrain>\n    <resource> terrain/" << base << ".terrain </resource>\n  </terrain>\n";
            // Samples are taken in the original frame and the grid is turned with the world;
            // one turn: new sample (i', j') is old sample (i = N-1-j', j = i').
            const int n = t->samples;
            std::vector<uint16_t> codes = terrainCodes.at(t);
            for (int k = 0; k < wt.turns(); ++k) {
                std::vector<uint16_t> turned(codes.size());
                for (int j = 0; j < n; ++j)
                    for (int i = 0; i < n; ++i) turned[size_t(j * n + i)] = codes[size_t(i * n + (n - 1 - j))];
                codes.swap(turned);
            }
            writeGreyPng(res / "terrain" / (base + ".png"), n, n, 16, codes);
            writeTextFile(res / "terrain" / (base + ".terrain"),
                          "<terrain>\n  <heights> " + base + ".png </heights>\n  <minHeight> " +
                              formatNumber(t->minHeight + wt.translation.y) + " </minHeight>\n  <maxHeight> " +
                              formatNumber(t->maxHeight + wt.translation.y) + " </maxHeight>\n</terrain>\n");
        }
        o << "</chunk>\n";
        writeTextFile(root / chunkName(id.gx, id.gz), o.str());
    }
}

}  // namespace shadowcull::testing
