// `shadowcull import`: glTF 2.0 scene -> space (docs/format.md, "glTF scenes").
//
// Everything is read and checked before anything is written: the node forest, every
// drawn mesh (decoded once however many nodes draw it), every transform, every light.
// Then the space is written into a fresh directory beside the output and renamed into
// place, so a failed import leaves nothing behind.

#include "gltf/gltf_import.h"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <nlohmann/json.hpp>
#include <tinyxml2.h>

#include "core/limits.h"
#include "gltf/glb_writer.h"
#include "io/file_read.h"
#include "io/gltf_document.h"
#include "util/format.h"
#include "util/hash.h"
#include "util/stop_request.h"

namespace shadowcull::gltf {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kPi = 3.14159265358979323846;

// Shortest text that reads back as the same double (transforms and light positions are
// written exactly: a scene 100 km from the origin keeps every bit of its placement).
std::string exact(double v) {
    char buf[32];
    auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
}

std::string exact3(const glm::dvec3& v) { return exact(v.x) + " " + exact(v.y) + " " + exact(v.z); }

struct Failure {
    std::string message;
};

[[noreturn]] void fail(std::string message) { throw Failure{std::move(message)}; }

// A signal stops the import between nodes, meshes and chunk files (a 200,000-node scene
// takes tens of seconds): thrown, so that write() removes its staging directory.
void stopIfRequested() {
    if (Status s = stopStatus(); !s) throw s.error();
}

// Whether process `pid` still runs (a signal 0 reaches it, or exists but is not ours).
bool processAlive(long pid) { return pid > 0 && (::kill(pid_t(pid), 0) == 0 || errno == EPERM); }

// Staging directories "<out>.import-<pid>" beside `out` that a killed import left (its
// process is gone: a running import's are left alone), removed. A second Ctrl-C, or
// SIGKILL, ends an import before it can remove its own (~32 MB for a large scene).
void removeStaleStaging(const fs::path& parent, const std::string& outName) {
    const std::string prefix = outName + ".import-";
    std::error_code ec;
    for (const fs::directory_entry& de : fs::directory_iterator(parent, ec)) {
        const std::string name = de.path().filename().string();
        if (name.compare(0, prefix.size(), prefix) != 0) continue;
        const std::string digits = name.substr(prefix.size());
        long pid = 0;
        const auto [end, err] = std::from_chars(digits.data(), digits.data() + digits.size(), pid);
        if (err != std::errc() || end != digits.data() + digits.size() || processAlive(pid)) continue;
        std::error_code rec;
        if (de.is_directory(rec) && !de.is_symlink(rec)) fs::remove_all(de.path(), rec);
    }
}

const json* member(const json& obj, const char* key) {
    if (!obj.is_object()) return nullptr;
    auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
}

// A node drawing a mesh, placed in world space (double precision throughout).
struct Placement {
    size_t node = 0;
    size_t mesh = 0;
    glm::dmat4 world{1.0};
    glm::dvec3 wsMin{0.0}, wsMax{0.0};  // world bounds of its triangles' vertices
    bool castsShadow = true;
    ChunkCoord chunk;
};

struct LightNode {
    size_t node = 0;
    glm::dmat4 world{1.0};
};

// Scale-invariant singularity test of a world transform's 3x3 part (the reader's test,
// RowTransform::isSingular, on the same rows).
bool singular(const glm::dmat4& m) {
    RowTransform t;
    for (int r = 0; r < 3; ++r) t.rows[size_t(r)] = glm::dvec3(m[r]);
    return t.isSingular();
}

bool finite(const glm::dmat4& m) {
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            if (!std::isfinite(m[c][r])) return false;
    return true;
}

// The largest entry of the 3x3 part, in magnitude.
double largestLinearEntry(const glm::dmat4& m) {
    double largest = 0.0;
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) largest = std::max(largest, std::abs(m[c][r]));
    return largest;
}

// Why the composed transform of a node that draws (`drawsMesh`) or lights something cannot
// place it, or "". A mesh goes into float geometry, so its scale is bounded; a light takes
// only its position and axis, so its scale matters only where it breaks the singularity
// test. Either way a huge scale is named as such, before the singularity test: a scale of
// 1e300 overflows the determinant, and "singular" would send the user looking for a
// flattened axis.
std::string transformProblem(const glm::dmat4& world, bool drawsMesh) {
    if (!finite(world)) return "the composed node transform is not finite";
    const double largest = largestLinearEntry(world);
    const bool isSingular = singular(world);
    if (!(largest <= limits::kMaxLinearEntry) && (drawsMesh || isSingular))
        return "the composed node transform scales by " + formatNumber(largest) + ", beyond the accepted " +
               formatNumber(limits::kMaxLinearEntry) + " (docs/format.md, accepted ranges)";
    if (isSingular) return "the composed node transform is singular (it flattens the node to a plane, a line or a point)";
    return "";
}

// A number in a node's extras: absent -> fallback; present -> a finite number >= 0.
double extrasLength(const json* extras, const char* key, double fallback, const std::string& where) {
    const json* v = extras ? member(*extras, key) : nullptr;
    if (!v) return fallback;
    if (!v->is_number() || !std::isfinite(v->get<double>()) || v->get<double>() < 0 ||
        v->get<double>() > limits::kMaxLength)
        fail(where + ".extras." + key + ": a number of metres in [0, " + formatNumber(limits::kMaxLength) + "] expected, got " +
             v->dump());
    return v->get<double>();
}

// Export writes the masks into a mesh node's `extras` and the lights into the root's: a
// value there that is not an object leaves no room for them, so it is refused at import,
// before anyone bakes a scene whose export must fail. `where` is "nodes[N]." or "".
void requireObjectExtras(const json& holder, const std::string& where, const char* what) {
    const json* extras = member(holder, "extras");
    if (!extras || extras->is_object()) return;
    std::string value = extras->dump();
    if (value.size() > 60) value = value.substr(0, 57) + "...";
    fail(where + "extras: an object expected (export writes the " + what + " into it), got " + value);
}

std::string sanitized(const std::string& name) {
    std::string out;
    for (char c : name) {
        if (out.size() >= 40) break;
        out += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
    }
    return out;
}

class Importer {
public:
    Importer(const ImportOptions& opt, GltfDocument& doc) : opt_(opt), doc_(doc) {}

    ImportReport run() {
        if (member(doc_.json(), "scenes") == nullptr || doc_.json()["scenes"].empty())
            fail("the file defines no scene (\"scenes\" is missing or empty): nothing says which nodes to import");
        Expected<std::vector<size_t>> roots = doc_.sceneRoots(opt_.scene);
        if (!roots) throw roots.error();
        requireObjectExtras(doc_.json(), "", "lights");
        findAnimated();
        placements_.reserve(doc_.nodes().size());
        walk(*roots);
        if (placements_.empty()) fail("the scene has no node that draws a mesh with triangles: nothing to bake");
        readLights();
        layout();
        stopIfRequested();
        write();
        return report_;
    }

private:
    // Nodes animation channels move, and skinned or morphed nodes: baked in the pose the
    // file stores, with a warning (a bake is of the static pose).
    void findAnimated() {
        const json* animations = member(doc_.json(), "animations");
        if (!animations || !animations->is_array()) return;
        for (const json& a : *animations) {
            const json* channels = member(a, "channels");
            if (!channels || !channels->is_array()) continue;
            for (const json& c : *channels)
                if (const json* target = member(c, "target"))
                    if (const json* n = member(*target, "node"); n && n->is_number_unsigned()) animated_.insert(n->get<size_t>());
        }
    }

    void walk(const std::vector<size_t>& roots) {
        const json& nodesJson = doc_.json()["nodes"];
        // Node, parent's world transform, whether an ancestor is animated, and the nearest
        // ancestor's extras.shadowcull_casts_shadow (gltfpack -kn moves the mesh of a named
        // node to an unnamed child: the setting stays on the named parent).
        std::vector<std::tuple<size_t, glm::dmat4, bool, std::optional<bool>>> stack;
        for (auto r = roots.rbegin(); r != roots.rend(); ++r) stack.emplace_back(*r, glm::dmat4(1.0), false, std::nullopt);
        while (!stack.empty()) {
            if (report_.nodes % 1024 == 0) stopIfRequested();
            auto [n, parentWorld, movedAbove, castsAbove] = stack.back();
            stack.pop_back();
            ++report_.nodes;
            const GltfNode& node = doc_.nodes()[n];
            const std::string where = gltfPath("nodes", n);
            const glm::dmat4 world = parentWorld * node.local;
            const bool moved = movedAbove || animated_.count(n) > 0;
            const json& nj = nodesJson[n];
            std::optional<bool> casts = castsAbove;
            if (const json* extras = member(nj, "extras")) {
                if (const json* c = member(*extras, "shadowcull_casts_shadow")) {
                    if (!c->is_boolean()) fail(where + ".extras.shadowcull_casts_shadow: true or false expected, got " + c->dump());
                    casts = c->get<bool>();
                }
            }
            for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.emplace_back(*c, world, moved, casts);
            if (!node.mesh && !node.light) continue;
            if (const std::string why = transformProblem(world, node.mesh.has_value()); !why.empty()) fail(where + ": " + why);
            if (node.light) lights_.push_back({n, world});
            if (!node.mesh) continue;
            if (moved || member(nj, "skin"))
                warn(where, std::string(member(nj, "skin") ? "skinned" : "animated") +
                                ": baked in the pose the file stores; its masks hold for that pose only");
            Expected<const std::vector<GltfPrimitive>*> prims = doc_.mesh(*node.mesh, where);
            if (!prims) throw prims.error();
            Placement p;
            p.node = n;
            p.mesh = *node.mesh;
            p.world = world;
            p.castsShadow = casts.value_or(true);
            bool any = false;
            size_t triangles = 0;
            for (const GltfPrimitive& prim : **prims) {
                if (prim.triangles.empty()) continue;
                triangles += prim.triangles.size();
                for (const glm::dvec3& q : prim.positions) {
                    const double lim = limits::kMaxLocalCoordinate;
                    if (!(std::abs(q.x) <= lim && std::abs(q.y) <= lim && std::abs(q.z) <= lim))
                        fail(gltfPath("meshes", p.mesh) + ": a position lies beyond the accepted " + formatNumber(lim) +
                             " m from the mesh origin (docs/format.md, accepted ranges)");
                    const glm::dvec3 w(world * glm::dvec4(q, 1.0));
                    p.wsMin = any ? glm::min(p.wsMin, w) : w;
                    p.wsMax = any ? glm::max(p.wsMax, w) : w;
                    any = true;
                }
            }
            if (!any) {
                warn(where, gltfPath("meshes", p.mesh) + " has no triangles (points or lines only): no model written");
                continue;
            }
            requireObjectExtras(nj, where + ".", "masks");
            report_.triangles += triangles;
            placements_.push_back(p);
        }
    }

    void readLights() {
        const json* defs = nullptr;
        if (const json* ext = member(doc_.json(), "extensions"))
            if (const json* lp = member(*ext, "KHR_lights_punctual")) defs = member(*lp, "lights");
        const std::string defsWhere = "extensions.KHR_lights_punctual.lights";
        for (const LightNode& ln : lights_) {
            const std::string where = gltfPath("nodes", ln.node);
            const size_t index = *doc_.nodes()[ln.node].light;
            if (!defs || !defs->is_array() || index >= defs->size())
                fail(where + ".extensions.KHR_lights_punctual.light: " + gltfPath(defsWhere, index) + " does not exist (" +
                     std::to_string(defs && defs->is_array() ? defs->size() : 0) + " defined)");
            const json& def = (*defs)[index];
            const std::string defWhere = gltfPath(defsWhere, index);
            if (!def.is_object()) fail(defWhere + ": object expected");
            const json* type = member(def, "type");
            if (!type || !type->is_string()) fail(defWhere + ".type: \"directional\", \"point\" or \"spot\" expected");
            Light L;
            const std::string t = type->get<std::string>();
            if (t == "directional") L.type = LightType::Directional;
            else if (t == "point") L.type = LightType::Point;
            else if (t == "spot") L.type = LightType::Spot;
            else fail(defWhere + ".type: unknown light type '" + t + "' (directional, point or spot)");
            const GltfNode& node = doc_.nodes()[ln.node];
            if (const json* name = member(def, "name"); name && name->is_string() && !name->get<std::string>().empty())
                L.name = name->get<std::string>();
            else L.name = node.name.empty() ? "light " + std::to_string(report_.sceneLights + 1) : node.name;
            // KHR_lights_punctual: lights shine along the node's -Z; point and spot lights sit
            // at its origin.
            L.position = glm::dvec3(ln.world[3]);
            const glm::dvec3 axis = -glm::dvec3(ln.world[2]);
            L.direction = axis / glm::length(axis);
            if (L.type != LightType::Directional) {
                if (!(std::abs(L.position.x) <= limits::kMaxWorldCoordinate && std::abs(L.position.y) <= limits::kMaxWorldCoordinate &&
                      std::abs(L.position.z) <= limits::kMaxWorldCoordinate))
                    fail(where + ": light position beyond the accepted " + formatNumber(limits::kMaxWorldCoordinate) + " m");
                L.range = lightRange(def, defWhere, where, L.name);
            }
            if (L.type == LightType::Spot) {
                double outer = kPi / 4;
                if (const json* spot = member(def, "spot")) {
                    if (const json* o = member(*spot, "outerConeAngle")) {
                        if (!o->is_number() || !(o->get<double>() > 0) || o->get<double>() > kPi / 2 + 1e-12)
                            fail(defWhere + ".spot.outerConeAngle: radians in (0, pi/2] expected, got " + o->dump());
                        outer = std::min(o->get<double>(), kPi / 2);
                    }
                }
                L.coneHalfAngleDeg = outer * 180.0 / kPi;
            }
            const json* extras = member(doc_.json()["nodes"][ln.node], "extras");
            L.bias = extrasLength(extras, "shadowcull_bias", opt_.bias, where);
            L.slopeBias = extrasLength(extras, "shadowcull_slope_bias", opt_.slopeBias, where);
            L.filterRadius = extrasLength(extras, "shadowcull_filter_radius", opt_.filterRadius, where);
            L.normalBias = extrasLength(extras, "shadowcull_normal_bias", opt_.normalBias, where);
            lightOut_.push_back(L);
            lightNodes_.push_back(long(ln.node));
            ++report_.sceneLights;
        }
        if (opt_.sun) {
            const double az = opt_.sun->azimuthDeg * kPi / 180, el = opt_.sun->elevationDeg * kPi / 180;
            Light sun;
            sun.name = "sun";
            sun.type = LightType::Directional;
            // Towards the sun: azimuth 0 = -Z (north), 90 = +X (east); light travels back.
            const glm::dvec3 toSun(std::sin(az) * std::cos(el), std::sin(el), -std::cos(az) * std::cos(el));
            sun.direction = -toSun;
            sun.bias = opt_.bias;
            sun.slopeBias = opt_.slopeBias;
            sun.filterRadius = opt_.filterRadius;
            sun.normalBias = opt_.normalBias;
            lightOut_.push_back(sun);
            lightNodes_.push_back(-1);
        }
        if (lightOut_.empty())
            fail("the scene has no KHR_lights_punctual light on its nodes; add one, or give --sun AZIMUTH,ELEVATION");
        if (lightOut_.size() > size_t(kMaxLights))
            fail(std::to_string(lightOut_.size()) + " lights (" + std::to_string(report_.sceneLights) +
                 " on the scene's nodes" + (opt_.sun ? " and --sun" : "") + "): a mask has 32 bits, at most 32 lights");
        report_.lights = lightOut_.size();
    }

    double lightRange(const json& def, const std::string& defWhere, const std::string& where, const std::string& name) {
        if (const json* r = member(def, "range")) {
            if (!r->is_number() || !(r->get<double>() > 0) || r->get<double>() > limits::kMaxLength)
                fail(defWhere + ".range: metres in (0, " + formatNumber(limits::kMaxLength) + "] expected, got " + r->dump());
            return r->get<double>();
        }
        double intensity = 1.0;
        if (const json* i = member(def, "intensity")) {
            if (!i->is_number() || !std::isfinite(i->get<double>()) || i->get<double>() < 0)
                fail(defWhere + ".intensity: a number >= 0 expected, got " + i->dump());
            intensity = i->get<double>();
        }
        // Candela over lux gives square metres: the distance where the light's illuminance
        // falls to the cut-off. Larger is conservative (more casters kept).
        double range = std::sqrt(intensity / opt_.lightCutoffLux);
        std::string note;
        if (!(range >= 0.01)) {
            range = 0.01;
            note = " (intensity " + formatNumber(intensity) + " cd: it lights nothing beyond 1 cm)";
        } else if (range > limits::kMaxLength) {
            range = limits::kMaxLength;
            note = " (capped at the accepted " + formatNumber(limits::kMaxLength) + " m)";
        }
        warn(where, "light '" + name + "' has no range: using " + formatNumber(range) + " m, where its intensity of " +
                        formatNumber(intensity) + " cd falls to " + formatNumber(opt_.lightCutoffLux) + " lux" + note +
                        "; set \"range\" in the file to choose");
        return range;
    }

    // Chunk of each placement, and the window that holds what matters (docs/format.md).
    void layout() {
        const double S = opt_.chunkSize.value_or(kDefaultChunkSize);
        if (!(S >= limits::kMinChunkSize && S <= limits::kMaxChunkSize))
            fail("--chunk-size " + formatNumber(S) + " is outside [" + formatNumber(limits::kMinChunkSize) + ", " +
                 formatNumber(limits::kMaxChunkSize) + "] m");
        report_.chunkSize = S;
        auto cell = [&](double v, const std::string& where) {
            const double c = std::floor(v / S);
            if (!(c >= -32768 && c <= 32767))
                fail(where + ": at " + formatNumber(v) + " m it lies outside the chunk grid (16-bit chunk indices of " +
                     formatNumber(S) + " m); use a larger --chunk-size");
            return int32_t(c);
        };
        int reach = 0;  // chunks any object's bounds reach beyond its own chunk
        int32_t x0 = INT32_MAX, x1 = INT32_MIN, z0 = INT32_MAX, z1 = INT32_MIN;
        size_t widest = 0;
        for (Placement& p : placements_) {
            const std::string where = gltfPath("nodes", p.node);
            const glm::dvec3 centre = 0.5 * (p.wsMin + p.wsMax);
            p.chunk = {cell(centre.x, where), cell(centre.z, where)};
            const int32_t ax = cell(p.wsMin.x, where), bx = cell(p.wsMax.x, where);
            const int32_t az = cell(p.wsMin.z, where), bz = cell(p.wsMax.z, where);
            const int r = std::max({p.chunk.x - ax, bx - p.chunk.x, p.chunk.z - az, bz - p.chunk.z});
            if (r > reach) {
                reach = r;
                widest = p.node;
            }
            x0 = std::min(x0, ax), x1 = std::max(x1, bx), z0 = std::min(z0, az), z1 = std::max(z1, bz);
            // The chunk file stores the transform relative to the chunk origin; the bake
            // accepts translations and placed vertices within 1e5 m of it.
            const glm::dvec3 origin(p.chunk.x * S, 0.0, p.chunk.z * S);
            const glm::dvec3 local = glm::dvec3(p.world[3]) - origin;
            const double far = std::max({std::abs(local.x), std::abs(local.y), std::abs(local.z),
                                         glm::length(p.wsMin - origin), glm::length(p.wsMax - origin)});
            if (!(far <= limits::kMaxLocalCoordinate))
                fail(where + ": its origin or bounds lie " + formatNumber(far) + " m from its chunk origin, beyond the accepted " +
                     formatNumber(limits::kMaxLocalCoordinate) + " m");
        }
        const int span = std::max(x1 - x0, z1 - z0);  // chunks between the scene's extremes
        const double across = std::max(x1 - x0, z1 - z0) * S + S;
        char buf[512];
        if (opt_.neighbours) {
            report_.neighbours = *opt_.neighbours;
            if (*opt_.neighbours < span)
                std::snprintf(buf, sizeof buf,
                              "--neighbours %d: each chunk is baked with %d chunks of %s m on each side loaded (a window of "
                              "%s m) by bake --method gpu; the scene spans %d x %d chunks, so its receivers farther away do not "
                              "count there (the analytic bake loads every chunk a shadow reaches)",
                              *opt_.neighbours, *opt_.neighbours, formatNumber(S).c_str(),
                              formatNumber((2 * *opt_.neighbours + 1) * S).c_str(), x1 - x0 + 1, z1 - z0 + 1);
            else
                std::snprintf(buf, sizeof buf, "--neighbours %d: every window holds the whole scene", *opt_.neighbours);
            if (*opt_.neighbours < reach)
                warn(gltfPath("nodes", widest),
                     "its bounds reach " + std::to_string(reach) + " chunks beyond its own, more than --neighbours " +
                         std::to_string(*opt_.neighbours) + ": bake --method gpu's windows centred farther away do not load it as a receiver");
        } else if (span <= kMaxAutoNeighbours) {
            report_.neighbours = span;
            std::snprintf(buf, sizeof buf,
                          "the scene spans %d x %d chunks of %s m: with %d neighbour%s on each side every window holds "
                          "the whole scene, so no receiver is left out",
                          x1 - x0 + 1, z1 - z0 + 1, formatNumber(S).c_str(), span, span == 1 ? "" : "s");
        } else {
            report_.neighbours = std::min(std::max(kLargeSceneNeighbours, reach), 64);
            std::snprintf(buf, sizeof buf,
                          "the scene is %s m across (%d x %d chunks of %s m), more than one window should hold: each chunk "
                          "is baked with %d chunks on each side loaded (%s m) by bake --method gpu, enough for its largest "
                          "object (%s); shadows falling farther than that do not count there (--neighbours widens it; "
                          "the analytic bake loads every chunk a shadow reaches)",
                          formatNumber(across).c_str(), x1 - x0 + 1, z1 - z0 + 1, formatNumber(S).c_str(),
                          report_.neighbours, formatNumber((2 * report_.neighbours + 1) * S).c_str(),
                          gltfPath("nodes", widest).c_str());
            if (reach > 64)
                warn(gltfPath("nodes", widest), "its bounds reach " + std::to_string(reach) +
                                                    " chunks beyond its own, more than the 64 neighbours a space may load; "
                                                    "use a larger --chunk-size");
        }
        report_.layout = buf;
    }

    void write() {
        const fs::path out(opt_.outDir);
        const fs::path parent = out.has_parent_path() ? out.parent_path() : fs::path(".");
        const fs::path temp = parent / (out.filename().string() + ".import-" + std::to_string(::getpid()));
        std::error_code ec;
        removeStaleStaging(parent, out.filename().string());
        fs::remove_all(temp, ec);
        try {
            fs::create_directories(temp / "models");
            writeSpace(temp);
            std::map<size_t, std::string> resources = writeMeshes(temp);
            writeChunks(temp, resources);
            stopIfRequested();  // the last moment: after the rename the space is complete
            // An empty directory is replaced by rename(2); anything else was refused earlier.
            if (fs::exists(out)) fs::remove(out);
            fs::rename(temp, out);
        } catch (const fs::filesystem_error& e) {
            fs::remove_all(temp, ec);
            throw makeError(ErrorKind::Io, e.path1().string(), 0, e.code().message() + " (nothing written)");
        } catch (...) {
            fs::remove_all(temp, ec);
            throw;
        }
    }

    static void writeFile(const fs::path& path, const std::string& bytes) {
        errno = 0;
        std::ofstream f(path, std::ios::binary);
        f.write(bytes.data(), std::streamsize(bytes.size()));
        f.close();
        if (!f)
            throw makeError(ErrorKind::Io, path.string(), 0,
                            "could not write: " + (errno ? errnoText(errno) : std::string("write failed")) + " (nothing written)");
    }

    void writeSpace(const fs::path& dir) {
        tinyxml2::XMLPrinter x;
        x.PushComment(" written by shadowcull import; see docs/format.md, \"glTF scenes\" ");
        x.OpenElement("space");
        x.OpenElement("chunkSize");
        x.PushText(exact(report_.chunkSize).c_str());
        x.CloseElement();
        x.OpenElement("neighbours");
        x.PushText(report_.neighbours);
        x.CloseElement();
        // Which scene this space was imported from: export refuses another one.
        x.OpenElement("gltfSource");
        x.PushAttribute("identity", sceneIdentity(doc_.json()).c_str());
        x.PushAttribute("nodes", uint64_t(doc_.nodes().size()));
        x.PushText(fs::path(opt_.scenePath).filename().string().c_str());
        x.CloseElement();
        for (size_t l = 0; l < lightOut_.size(); ++l) {
            const Light& L = lightOut_[l];
            x.OpenElement("light");
            auto text = [&](const char* name, const std::string& value) {
                x.OpenElement(name);
                x.PushText(value.c_str());
                x.CloseElement();
            };
            text("name", L.name);
            text("type", lightTypeName(L.type));
            if (L.type != LightType::Point) text("direction", exact3(L.direction));
            if (L.type != LightType::Directional) {
                text("position", exact3(L.position));
                text("range", exact(L.range));
            }
            if (L.type == LightType::Spot) text("coneAngle", exact(L.coneHalfAngleDeg));
            text("bias", exact(L.bias));
            text("slopeBias", exact(L.slopeBias));
            text("filterRadius", exact(L.filterRadius));
            if (L.normalBias > 0) text("normalBias", exact(L.normalBias));
            x.OpenElement("gltf");
            if (lightNodes_[l] >= 0) {
                x.PushAttribute("node", int64_t(lightNodes_[l]));
                x.PushAttribute("name", doc_.nodes()[size_t(lightNodes_[l])].name.c_str());
            } else {
                x.PushAttribute("sun", "--sun");
            }
            x.CloseElement();
            x.CloseElement();
        }
        x.CloseElement();
        writeFile(dir / "space.xml", x.CStr());
    }

    std::map<size_t, std::string> writeMeshes(const fs::path& dir) {
        std::map<size_t, std::string> resources;
        for (const Placement& p : placements_) {
            if (resources.count(p.mesh)) continue;
            stopIfRequested();
            const std::vector<GltfPrimitive>& prims = **doc_.mesh(p.mesh, gltfPath("nodes", p.node));
            std::string name;
            if (const json* m = member(doc_.json()["meshes"][p.mesh], "name"); m && m->is_string()) name = m->get<std::string>();
            const std::string file = "models/mesh" + std::to_string(p.mesh) + (name.empty() ? "" : "_" + sanitized(name)) + ".glb";
            writeFile(dir / file, meshGlb(prims, name));
            resources[p.mesh] = file;
        }
        report_.meshes = resources.size();
        return resources;
    }

    void writeChunks(const fs::path& dir, const std::map<size_t, std::string>& resources) {
        std::map<ChunkCoord, std::vector<const Placement*>> chunks;
        for (const Placement& p : placements_) chunks[p.chunk].push_back(&p);
        const double S = report_.chunkSize;
        for (const auto& [coord, list] : chunks) {
            stopIfRequested();
            tinyxml2::XMLPrinter x;
            x.OpenElement("chunk");
            for (const Placement* p : list) {
                const GltfNode& node = doc_.nodes()[p->node];
                x.OpenElement("model");
                x.OpenElement("resource");
                x.PushText(resources.at(p->mesh).c_str());
                x.CloseElement();
                x.OpenElement("uuid");
                x.PushText(nodeUuid(p->node, node.name).c_str());
                x.CloseElement();
                x.OpenElement("gltf");
                x.PushAttribute("node", uint64_t(p->node));
                x.PushAttribute("name", node.name.c_str());
                x.PushAttribute("mesh", uint64_t(p->mesh));
                x.CloseElement();
                x.OpenElement("transform");
                const glm::dvec3 origin(coord.x * S, 0.0, coord.z * S);
                // Row-vector convention: row r is the image of axis r (glm column r).
                // XMLPrinter keeps the element name pointer until CloseElement.
                static const char* const kRows[] = {"row0", "row1", "row2"};
                for (int r = 0; r < 3; ++r) {
                    x.OpenElement(kRows[r]);
                    x.PushText(exact3(glm::dvec3(p->world[r])).c_str());
                    x.CloseElement();
                }
                x.OpenElement("row3");
                x.PushText(exact3(glm::dvec3(p->world[3]) - origin).c_str());
                x.CloseElement();
                x.CloseElement();
                if (!p->castsShadow) {
                    x.OpenElement("castsShadow");
                    x.PushText("false");
                    x.CloseElement();
                }
                x.CloseElement();
                ++report_.models;
            }
            x.CloseElement();
            writeFile(dir / chunkFileName(coord), x.CStr());
        }
        report_.chunks = chunks.size();
    }

    void warn(const std::string& where, const std::string& message) {
        report_.warnings.push_back({opt_.scenePath, 0, where + ": " + message});
    }

    const ImportOptions& opt_;
    GltfDocument& doc_;
    std::set<size_t> animated_;
    std::vector<Placement> placements_;
    std::vector<LightNode> lights_;
    std::vector<Light> lightOut_;
    std::vector<long> lightNodes_;  // per light: its node, -1 for --sun
    ImportReport report_;
};

// The output must be new (or an empty directory): import never mixes its files with
// someone else's.
Status checkOutput(const ImportOptions& opt) {
    std::error_code ec;
    const fs::path out(opt.outDir);
    if (!fs::exists(fs::symlink_status(out, ec))) return Status::ok();
    if (!fs::is_directory(out, ec))
        return makeError(ErrorKind::Io, opt.outDir, 0, "exists and is not a directory; import writes a new space (nothing written)");
    if (!fs::is_empty(out, ec))
        return makeError(ErrorKind::Io, opt.outDir, 0,
                         "exists and is not empty; import writes a new space and never mixes it with other files (nothing written)");
    return Status::ok();
}

}  // namespace

std::string nodeUuid(size_t node, const std::string& name) {
    char buf[48];
    const uint64_t h = Hasher().str(name).value();
    std::snprintf(buf, sizeof buf, "474C5446-%08X-%08X-%08X", unsigned(node), unsigned(h >> 32), unsigned(h & 0xffffffffu));
    return buf;
}

std::optional<size_t> nodeFromUuid(const std::string& uuid) {
    if (uuid.size() != 35 || uuid.compare(0, 9, "474C5446-") != 0 || uuid[17] != '-' || uuid[26] != '-') return std::nullopt;
    size_t node = 0;
    for (size_t k = 9; k < 17; ++k) {
        const char c = uuid[k];
        const int v = c >= '0' && c <= '9' ? c - '0' : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
        if (v < 0) return std::nullopt;
        node = node * 16 + size_t(v);
    }
    return node;
}

std::string sceneIdentity(const json& gltf) {
    // Member by member (keys are sorted), so that only an `extras` holding "shadowcull" is
    // ever copied: a copy and a dump of the whole document cost a third of import's memory
    // on large scenes. An `extras` left empty by the stripping counts as absent, so a scene
    // and its export have the same identity.
    Hasher h;
    auto hashStripped = [&](const json& value) {
        auto e = value.is_object() ? value.find("extras") : value.end();
        if (e == value.end() || !e->is_object() || !e->contains("shadowcull")) {
            h.str(value.dump());
            return;
        }
        json copy = value;
        copy["extras"].erase("shadowcull");
        if (copy["extras"].empty()) copy.erase("extras");
        h.str(copy.dump());
    };
    if (!gltf.is_object()) return "0000000000000000";
    for (auto it = gltf.begin(); it != gltf.end(); ++it) {
        if (it.key() == "extras" && it->is_object()) {
            json extras = *it;
            extras.erase("shadowcull");
            if (extras.empty()) continue;
            h.str(it.key()).str(extras.dump());
        } else if (it.key() == "nodes" && it->is_array()) {
            h.str(it.key()).pod(uint64_t(it->size()));
            for (const json& node : *it) hashStripped(node);
        } else {
            h.str(it.key()).str(it->dump());
        }
    }
    char buf[20];
    std::snprintf(buf, sizeof buf, "%016llx", (unsigned long long)h.value());
    return buf;
}

Expected<ImportReport> importScene(const ImportOptions& opt) {
    if (Status s = checkOutput(opt); !s) return s.error();
    try {
        Expected<GltfDocument> doc = GltfDocument::open(opt.scenePath);
        if (!doc) throw doc.error();
        if (Status s = stopStatus(); !s) return makeError(ErrorKind::Interrupted, "", 0, s.error().message + " (nothing written)");
        Importer importer(opt, *doc);
        ImportReport report = importer.run();
        for (const Diagnostic& d : doc->warnings()) report.warnings.push_back(d);
        return report;
    } catch (const Failure& f) {
        return makeError(ErrorKind::BadInput, opt.scenePath, 0, f.message + " (nothing written)");
    } catch (const Error& e) {
        Error copy = e;
        if (copy.kind == ErrorKind::Interrupted) copy.message += "; the staging directory was removed";
        if (copy.kind != ErrorKind::Io) copy.message += " (nothing written)";
        return copy;
    }
}

}  // namespace shadowcull::gltf
