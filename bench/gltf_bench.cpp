// gltf_bench: what `shadowcull import` costs on a large glTF scene (bench/README.md,
// docs/performance.md "Importing glTF scenes").
//
//   gltf_bench [--nodes N[,N...]] [--meshes M[,M...]] [--work DIR] [--json FILE] [--repeat R] [--keep]
//
// Per size (N rock nodes drawing M unique rock meshes; lists are paired, so
// `--nodes 10000,40000 --meshes 500,2000` measures two sizes in one run), it generates a
// scene with a fixed seed and writes it as a .glb: N closed random rocks (subdivided
// icosahedra, 320 triangles, radially jittered) placed with random position, rotation and
// scale over 2 km x 2 km, in groups of 20 under a parent node with its own transform, on
// a ground of 50 m tiles, lit by one directional light node. Then it runs the real CLI,
// the `shadowcull` next to this executable:
//
//   shadowcull import SCENE.glb SPACE            the scene as generated (instanced)
//   shadowcull bake SPACE --dry-run --quiet --chunk 00000000o   one central chunk
//   shadowcull import COPIES.glb SPACE2          the same nodes, each with its own copy of
//                                                its mesh (no instancing): the memory reference
//
// Each run is its own child process (fork + exec) and its peak RSS is the child's
// ru_maxrss from wait4. Scene generation also runs in a child, so that this process stays
// small: a forked child's RSS starts at its parent's, and Linux keeps that high-water
// mark across exec.

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "bench/machine.h"
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#include "tests/support/gltf_scenes.h"

using nlohmann::json;
using shadowcull::testing::GltfSceneBuilder;
using shadowcull::bench::cpuModel;
using shadowcull::bench::procStatusKiB;
namespace fs = std::filesystem;

namespace {

constexpr uint64_t kSeed = 0x67C7F5EEDull;     // fixed: the same options write the same bytes
constexpr int kGroupSize = 20;                 // rock nodes under each group node
constexpr double kHalfArea = 1000.0;           // the scene covers [-1000, 1000] m in x and z
constexpr double kTile = 50.0;                 // ground tile side, metres
constexpr double kGroupRadius = 30.0;          // rocks lie within this of their group's origin
constexpr int kSubdivisions = 2;               // icosahedron subdivided twice: 320 triangles
const char* const kCentralChunk = "00000000o"; // chunk (0, 0): [0, 64) m x [0, 64) m

struct Options {
    std::vector<long> nodes{40000};
    std::vector<long> meshes{2000};
    fs::path work = fs::temp_directory_path() / "shadowcull-gltf-bench";
    std::string jsonOut;
    int repeat = 3;  // runs of the instanced import and of the bake; the median is reported
    bool keep = false;
};

[[noreturn]] void usage(const std::string& why) {
    std::fprintf(stderr,
                 "gltf_bench: %s\n"
                 "usage: gltf_bench [--nodes N[,N...]] [--meshes M[,M...]] [--work DIR] [--json FILE] [--repeat R] [--keep]\n"
                 "  --nodes   rock nodes per scene (default 40000); a list measures several sizes in one run\n"
                 "  --meshes  unique rock meshes, paired with --nodes (default 2000)\n"
                 "  --work    where scenes and spaces are written (default $TMPDIR/shadowcull-gltf-bench)\n"
                 "  --json    every figure as JSON\n"
                 "  --repeat  runs of the instanced import and of the bake, median reported (default 3)\n"
                 "  --keep    keep the scenes and spaces (default: each size's files are removed once measured)\n",
                 why.c_str());
    std::exit(2);
}

std::vector<long> counts(const std::string& text, const std::string& option) {
    std::vector<long> out;
    std::stringstream ss(text);
    for (std::string s; std::getline(ss, s, ',');) {
        char* end = nullptr;
        const long n = std::strtol(s.c_str(), &end, 10);
        if (s.empty() || *end || n < 1) usage(option + ": positive counts expected, got '" + text + "'");
        out.push_back(n);
    }
    if (out.empty()) usage(option + ": a count expected");
    return out;
}

Options parseArgs(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) usage("missing value after " + a);
            return argv[++i];
        };
        if (a == "--nodes") o.nodes = counts(value(), a);
        else if (a == "--meshes") o.meshes = counts(value(), a);
        else if (a == "--work") o.work = value();
        else if (a == "--json") o.jsonOut = value();
        else if (a == "--keep") o.keep = true;
        else if (a == "--repeat") {
            const std::vector<long> r = counts(value(), a);
            if (r.size() != 1) usage("--repeat: one count expected");
            o.repeat = int(r[0]);
        }
        else if (a == "-h" || a == "--help") usage("help");
        else usage("unknown option " + a);
    }
    if (o.nodes.size() != o.meshes.size()) usage("--nodes and --meshes must list as many sizes");
    for (size_t k = 0; k < o.nodes.size(); ++k)
        if (o.meshes[k] > o.nodes[k]) usage("more unique meshes than rock nodes: some meshes would be drawn by no node");
    return o;
}

std::string fmt(const char* f, ...) {
    char buf[512];
    va_list ap;
    va_start(ap, f);
    std::vsnprintf(buf, sizeof buf, f, ap);
    va_end(ap);
    return buf;
}

std::string thousands(double v) {
    std::string s = fmt("%.0f", v), out;
    const size_t digits = s.size() - (s[0] == '-' ? 1 : 0);
    for (size_t k = 0; k < s.size(); ++k) {
        out += s[k];
        const size_t left = s.size() - 1 - k;
        if (left > 0 && left % 3 == 0 && (s[0] != '-' || k > 0) && digits > 3) out += ',';
    }
    return out;
}

std::string mib(double kib) { return kib >= 1024.0 * 1024.0 ? fmt("%.2f GiB", kib / 1048576.0) : fmt("%.0f MiB", kib / 1024.0); }
std::string megabytes(double bytes) { return fmt("%.1f MB", bytes / 1e6); }

double since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

double memTotalGiB() {
    std::ifstream in("/proc/meminfo");
    for (std::string line; std::getline(in, line);)
        if (line.rfind("MemTotal:", 0) == 0) return std::atof(line.c_str() + 9) / 1048576.0;
    return 0;
}

std::string loadAverage() {
    double l[3] = {0, 0, 0};
    if (getloadavg(l, 3) != 3) return "?";
    return fmt("%.2f %.2f %.2f", l[0], l[1], l[2]);
}

// ---------------------------------------------------------------------------------------
// Child processes

struct Run {
    int exitCode = -1;      // -1: did not exit normally
    std::string failure;    // empty when it exited (whatever the code)
    double wall = 0, cpu = 0, sys = 0;  // cpu: user + system; sys: system alone
    long maxRssKiB = 0;
    long minorFaults = 0;
    int repeats = 1;             // runs behind this figure (median wall time)
    double wallMin = 0, wallMax = 0;
    long parentRssKiB = 0;  // this process's VmRSS when it forked (the child's RSS floor)
};

Run finish(pid_t pid, std::chrono::steady_clock::time_point t0, long parentRss) {
    Run r;
    r.parentRssKiB = parentRss;
    int status = 0;
    rusage ru{};
    while (wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
    }
    r.wall = r.wallMin = r.wallMax = since(t0);
    r.cpu = double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    r.sys = double(ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_stime.tv_usec);
    r.maxRssKiB = ru.ru_maxrss;
    r.minorFaults = ru.ru_minflt;
    if (WIFEXITED(status)) r.exitCode = WEXITSTATUS(status);
    else if (WIFSIGNALED(status)) r.failure = fmt("killed by signal %d (%s)", WTERMSIG(status), strsignal(WTERMSIG(status)));
    else r.failure = "did not exit";
    return r;
}

// Forks: the child runs `child`, which does not return (it ends with _exit); the parent
// waits for it and measures it.
template <class F>
Run forkAndMeasure(F&& child) {
    const long parentRss = procStatusKiB("VmRSS:");
    std::fflush(stdout);
    std::fflush(stderr);
    const auto t0 = std::chrono::steady_clock::now();
    const pid_t pid = fork();
    if (pid < 0) {
        std::perror("gltf_bench: fork");
        std::exit(1);
    }
    if (pid == 0) child();
    return finish(pid, t0, parentRss);
}

// Runs `argv` with stdout and stderr into files; waits.
Run runProgram(const std::vector<std::string>& argv, const fs::path& out, const fs::path& err) {
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    return forkAndMeasure([&] {
        const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (o < 0 || e < 0 || dup2(o, 1) < 0 || dup2(e, 2) < 0) _exit(126);
        ::close(o);
        ::close(e);
        execv(args[0], args.data());
        std::fprintf(stderr, "gltf_bench: exec %s: %s\n", args[0], std::strerror(errno));
        _exit(127);
    });
}

// Runs `body` in a forked child (exit code = its return value).
template <class F>
Run runChild(F&& body) {
    return forkAndMeasure([&] {
        int code = 1;
        try {
            code = body();
        } catch (const std::exception& e) {
            std::fprintf(stderr, "gltf_bench: %s\n", e.what());
        }
        std::fflush(stdout);
        std::fflush(stderr);
        _exit(code);
    });
}

std::string readText(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// ---------------------------------------------------------------------------------------
// The scene

// SplitMix64: deterministic on every platform (no std distributions).
struct Rng {
    uint64_t s;
    explicit Rng(uint64_t seed) : s(seed) {}
    uint64_t next() {
        uint64_t z = (s += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    double uniform() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)
    double range(double a, double b) { return a + (b - a) * uniform(); }
    size_t below(size_t n) { return size_t(next() % n); }
    // Uniform random rotation (Shoemake).
    glm::dquat rotation() {
        const double u1 = uniform(), u2 = 2 * M_PI * uniform(), u3 = 2 * M_PI * uniform();
        const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
        return glm::normalize(glm::dquat(b * std::cos(u3), a * std::sin(u2), a * std::cos(u2), b * std::sin(u3)));
    }
};

// Unit icosphere: directions and triangles, each counter-clockwise seen from outside.
struct Icosphere {
    std::vector<glm::dvec3> dirs;
    std::vector<std::array<uint32_t, 3>> tris;
};

Icosphere icosphere(int subdivisions) {
    Icosphere s;
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    const double v[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                             {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (const auto& p : v) s.dirs.push_back(glm::normalize(glm::dvec3(p[0], p[1], p[2])));
    s.tris = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
              {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8}, {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    for (int level = 0; level < subdivisions; ++level) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            const auto key = std::minmax(a, b);
            auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            s.dirs.push_back(glm::normalize(s.dirs[a] + s.dirs[b]));
            return mid[key] = uint32_t(s.dirs.size() - 1);
        };
        std::vector<std::array<uint32_t, 3>> next;
        for (const auto& f : s.tris) {
            const uint32_t ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]), ca = midpoint(f[2], f[0]);
            next.push_back({f[0], ab, ca});
            next.push_back({f[1], bc, ab});
            next.push_back({f[2], ca, bc});
            next.push_back({ab, bc, ca});
        }
        s.tris = std::move(next);
    }
    // Wind every triangle outward (the table above is, but do not rely on it).
    for (auto& f : s.tris)
        if (glm::dot(glm::cross(s.dirs[f[1]] - s.dirs[f[0]], s.dirs[f[2]] - s.dirs[f[0]]), s.dirs[f[0]]) < 0) std::swap(f[1], f[2]);
    return s;
}

// A closed random rock about 1 m in radius: every vertex moved along its direction by a
// positive factor (jitter plus a few smooth bumps), then scaled by a positive diagonal.
// Both keep det(a, b, c) > 0 for every triangle (a, b, c) of the star-shaped sphere, so
// every triangle stays counter-clockwise seen from outside and non-degenerate; checked.
GltfSceneBuilder::Primitive rockPrimitive(const Icosphere& sphere, Rng& rng, long material) {
    GltfSceneBuilder::Primitive p;
    p.material = material;
    const glm::dvec3 axes(rng.range(0.75, 1.3), rng.range(0.45, 0.9), rng.range(0.75, 1.3));
    glm::dvec3 bumpDir[3];
    double bumpHeight[3];
    for (int k = 0; k < 3; ++k) {
        bumpDir[k] = glm::normalize(glm::dvec3(rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)) + glm::dvec3(0, 0, 1e-9));
        bumpHeight[k] = rng.range(-0.2, 0.3);
    }
    for (const glm::dvec3& d : sphere.dirs) {
        double r = 1.0 + rng.range(-0.12, 0.12);
        for (int k = 0; k < 3; ++k) r += bumpHeight[k] * std::pow(std::max(0.0, glm::dot(d, bumpDir[k])), 3.0);
        r = std::max(r, 0.35);
        p.positions.push_back(glm::vec3(axes * (r * d)));
    }
    for (const auto& f : sphere.tris) {
        const glm::dvec3 a(p.positions[f[0]]), b(p.positions[f[1]]), c(p.positions[f[2]]);
        const glm::dvec3 n = glm::cross(b - a, c - a);
        if (!(glm::dot(n, a) > 0) || !(glm::length(n) > 1e-8)) {
            std::fprintf(stderr, "gltf_bench: internal error: a rock triangle is degenerate or inward\n");
            std::exit(5);
        }
        p.indices.insert(p.indices.end(), {f[0], f[1], f[2]});
    }
    return p;
}

struct SceneStats {
    long nodes = 0, meshNodes = 0, rockNodes = 0, groupNodes = 0, tiles = 0, uniqueMeshes = 0;
    long placedTriangles = 0, meshTriangles = 0;
    double fileBytes = 0, genSeconds = 0;
    json toJson() const {
        return {{"nodes", nodes},           {"meshNodes", meshNodes},   {"rockNodes", rockNodes},
                {"groupNodes", groupNodes}, {"groundTiles", tiles},     {"uniqueMeshes", uniqueMeshes},
                {"placedTriangles", placedTriangles}, {"uniqueMeshTriangles", meshTriangles},
                {"fileBytes", fileBytes},   {"generationSeconds", genSeconds}};
    }
};

// The scene of `rocks` rock nodes drawing `uniqueRocks` meshes. `instanced` false: every
// mesh node gets its own copy of the mesh it would share (same nodes, same placements,
// same triangles; one mesh per node).
SceneStats writeScene(long rocks, long uniqueRocks, bool instanced, const fs::path& file) {
    const auto t0 = std::chrono::steady_clock::now();
    SceneStats st;
    GltfSceneBuilder b;
    const long rockMaterial = long(b.material("rock", false, false));
    const long groundMaterial = long(b.material("ground", false, false));
    const Icosphere sphere = icosphere(kSubdivisions);
    Rng meshRng(kSeed);
    std::vector<GltfSceneBuilder::Primitive> shapes;
    for (long m = 0; m < uniqueRocks; ++m) shapes.push_back(rockPrimitive(sphere, meshRng, rockMaterial));
    const GltfSceneBuilder::Primitive tile = shadowcull::testing::squarePrimitive(float(kTile / 2), 0.0f, 0.0f, 0.0f, groundMaterial);

    std::vector<size_t> rockMesh;
    size_t tileMesh = 0;
    if (instanced) {
        for (long m = 0; m < uniqueRocks; ++m) rockMesh.push_back(b.mesh("rock_" + std::to_string(m), {shapes[size_t(m)]}));
        tileMesh = b.mesh("ground_tile", {tile});
    }
    auto meshFor = [&](long shape, const std::string& name) -> size_t {
        if (instanced) return rockMesh[size_t(shape)];
        return b.mesh(name, {shapes[size_t(shape)]});
    };

    const size_t sun = b.node("Sun", -1, glm::dvec3(0, 200, 0), shadowcull::testing::aimMinusZ({0.35, -0.8, 0.25}));
    b.setLight(sun, {{"type", "directional"}, {"name", "sun"}, {"intensity", 3.0}});
    const long ground = long(b.node("Ground", -1));
    const int tilesPerSide = int(2 * kHalfArea / kTile);
    for (int i = 0; i < tilesPerSide; ++i)
        for (int j = 0; j < tilesPerSide; ++j) {
            const std::string name = "tile_" + std::to_string(i) + "_" + std::to_string(j);
            const size_t n = b.node(name, ground, glm::dvec3(-kHalfArea + (i + 0.5) * kTile, 0.0, -kHalfArea + (j + 0.5) * kTile));
            b.setMesh(n, instanced ? tileMesh : b.mesh(name, {tile}));
            ++st.tiles;
        }

    Rng rng(kSeed ^ 0x5EED0F0C0A57ull);
    const double margin = kGroupRadius * 1.3 + 10.0;
    long group = -1;
    for (long k = 0; k < rocks; ++k) {
        if (k % kGroupSize == 0) {
            const glm::dvec3 at(rng.range(-kHalfArea + margin, kHalfArea - margin), 0.0, rng.range(-kHalfArea + margin, kHalfArea - margin));
            const glm::dquat yaw = glm::angleAxis(rng.range(0, 2 * M_PI), glm::dvec3(0, 1, 0));
            group = long(b.node("group_" + std::to_string(k / kGroupSize), -1, at, yaw, glm::dvec3(rng.range(0.8, 1.25))));
            ++st.groupNodes;
        }
        // Every unique mesh is drawn at least once; then at random.
        const long shape = k < uniqueRocks ? k : long(rng.below(size_t(uniqueRocks)));
        const double angle = rng.range(0, 2 * M_PI), dist = kGroupRadius * std::sqrt(rng.uniform());
        const double s = std::exp(rng.range(std::log(0.5), std::log(4.0)));  // 0.5 .. 4 m, log-uniform
        const glm::dvec3 scale(s * rng.range(0.85, 1.15), s * rng.range(0.85, 1.15), s * rng.range(0.85, 1.15));
        const glm::dvec3 at(dist * std::cos(angle), 0.3 * s, dist * std::sin(angle));  // partly buried
        const std::string name = "rock_" + std::to_string(k);
        const size_t n = b.node(name, group, at, rng.rotation(), scale);
        b.setMesh(n, meshFor(shape, name));
        ++st.rockNodes;
    }
    st.meshNodes = st.rockNodes + st.tiles;
    st.nodes = long(b.doc()["nodes"].size());
    st.uniqueMeshes = long(b.doc()["meshes"].size());
    st.meshTriangles = uniqueRocks * long(sphere.tris.size()) + 2;
    st.placedTriangles = st.rockNodes * long(sphere.tris.size()) + 2 * st.tiles;
    {
        const std::string bytes = b.glb();
        std::ofstream out(file, std::ios::binary);
        out.write(bytes.data(), std::streamsize(bytes.size()));
        if (!out) throw std::runtime_error("could not write " + file.string());
        st.fileBytes = double(bytes.size());
    }
    st.genSeconds = since(t0);
    return st;
}

// ---------------------------------------------------------------------------------------
// Outputs

struct SpaceStats {
    long chunks = 0, resources = 0;
    double bytes = 0;
    int neighbours = -1;
    long windowChunks = 0, windowModels = 0, centreModels = 0;
};

long countOf(const std::string& text, const std::string& what) {
    long n = 0;
    for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
    return n;
}

SpaceStats spaceStats(const fs::path& dir) {
    SpaceStats s;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file()) {
            s.bytes += double(e.file_size());
            if (e.path().extension() == ".chunk" && e.path().parent_path() == dir) ++s.chunks;
            if (e.path().extension() == ".glb" && e.path().parent_path().filename() == "models") ++s.resources;
        }
    const std::string space = readText(dir / "space.xml");
    const size_t at = space.find("<neighbours>");
    if (at != std::string::npos) s.neighbours = std::atoi(space.c_str() + at + 12);
    // The window of the central chunk (0, 0): the chunks the dry-run bake loads.
    for (int x = -std::max(s.neighbours, 0); x <= s.neighbours; ++x)
        for (int z = -std::max(s.neighbours, 0); z <= s.neighbours; ++z) {
            const fs::path f = dir / fmt("%04x%04xo.chunk", unsigned(uint16_t(x)), unsigned(uint16_t(z)));
            if (!fs::exists(f)) continue;
            const long models = countOf(readText(f), "<model>");
            ++s.windowChunks;
            s.windowModels += models;
            if (x == 0 && z == 0) s.centreModels = models;
        }
    return s;
}

json runJson(const Run& r) {
    return {{"exitCode", r.exitCode}, {"failure", r.failure}, {"wallSeconds", r.wall}, {"cpuSeconds", r.cpu},
            {"systemSeconds", r.sys}, {"peakRssKiB", r.maxRssKiB}, {"minorFaults", r.minorFaults}, {"parentRssKiB", r.parentRssKiB},
            {"repeats", r.repeats}, {"wallMinSeconds", r.wallMin}, {"wallMaxSeconds", r.wallMax}};
}

json spaceJson(const SpaceStats& s) {
    return {{"chunks", s.chunks}, {"modelResources", s.resources}, {"bytes", s.bytes}, {"neighbours", s.neighbours},
            {"centralWindowChunks", s.windowChunks}, {"centralWindowModels", s.windowModels}, {"centralChunkModels", s.centreModels}};
}

struct SizeResult {
    long rocks = 0, meshes = 0;
    bool ok = false;
    std::string failure;
    SceneStats scene, copies;
    Run gen, genCopies, import, importCopies, bake;
    SpaceStats space, spaceCopies;
    std::string importLine, windowsLine;
};

std::string firstLineWith(const std::string& text, const std::string& prefix) {
    std::stringstream ss(text);
    for (std::string line; std::getline(ss, line);)
        if (line.rfind(prefix, 0) == 0) return line;
    return "";
}

bool generate(long rocks, long meshes, bool instanced, const fs::path& file, SceneStats& stats, Run& run) {
    const fs::path meta = file.string() + ".json";
    run = runChild([&] {
        const SceneStats s = writeScene(rocks, meshes, instanced, file);
        std::ofstream(meta) << s.toJson().dump() << "\n";
        return 0;
    });
    if (run.exitCode != 0) return false;
    const json j = json::parse(readText(meta));
    stats.nodes = j["nodes"];
    stats.meshNodes = j["meshNodes"];
    stats.rockNodes = j["rockNodes"];
    stats.groupNodes = j["groupNodes"];
    stats.tiles = j["groundTiles"];
    stats.uniqueMeshes = j["uniqueMeshes"];
    stats.placedTriangles = j["placedTriangles"];
    stats.meshTriangles = j["uniqueMeshTriangles"];
    stats.fileBytes = j["fileBytes"];
    stats.genSeconds = j["generationSeconds"];
    return true;
}

// The run of median wall time; the peak RSS is the largest of all (they agree to a few
// hundred KiB: the same work).
Run median(std::vector<Run> runs) {
    long peak = 0;
    for (const Run& r : runs) peak = std::max(peak, r.maxRssKiB);
    std::sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) { return a.wall < b.wall; });
    Run m = runs[runs.size() / 2];
    m.maxRssKiB = peak;
    m.repeats = int(runs.size());
    m.wallMin = runs.front().wall;
    m.wallMax = runs.back().wall;
    return m;
}

std::string describe(const Run& r) {
    return r.failure.empty() ? fmt("exit code %d", r.exitCode) : r.failure;
}

SizeResult measure(const fs::path& cli, const Options& o, long rocks, long meshes) {
    SizeResult res;
    res.rocks = rocks;
    res.meshes = meshes;
    const fs::path dir = o.work / fmt("n%ld-m%ld", rocks, meshes);
    std::error_code ec;
    fs::remove_all(dir, ec);
    fs::create_directories(dir);
    auto fail = [&](const std::string& what, const Run& r, const fs::path& err) {
        res.failure = what + ": " + describe(r);
        const std::string text = err.empty() ? "" : readText(err);
        if (!text.empty()) res.failure += " (" + text.substr(0, 400) + ")";
        std::fprintf(stderr, "gltf_bench: %s\n", res.failure.c_str());
        return res;
    };

    // Instanced scene: generate, import, bake one central chunk.
    std::fprintf(stderr, "gltf_bench: %ld rock nodes / %ld meshes: generating...\n", rocks, meshes);
    const fs::path scene = dir / "scene.glb", space = dir / "space";
    if (!generate(rocks, meshes, true, scene, res.scene, res.gen)) return fail("generating the scene", res.gen, {});
    std::fprintf(stderr, "gltf_bench:   %s, %.1f s; importing...\n", megabytes(res.scene.fileBytes).c_str(), res.scene.genSeconds);
    std::vector<Run> imports;
    for (int k = 0; k < o.repeat; ++k) {
        fs::remove_all(space, ec);
        imports.push_back(runProgram({cli.string(), "import", scene.string(), space.string()}, dir / "import.out", dir / "import.err"));
        if (imports.back().exitCode != 0) return fail("shadowcull import", imports.back(), dir / "import.err");
    }
    res.import = median(imports);
    const std::string importOut = readText(dir / "import.out");
    res.importLine = firstLineWith(importOut, "imported ");
    res.windowsLine = firstLineWith(importOut, "windows: ");
    res.space = spaceStats(space);
    std::fprintf(stderr, "gltf_bench:   import %.2f s, %s; bake --dry-run --chunk %s...\n", res.import.wall,
                 mib(double(res.import.maxRssKiB)).c_str(), kCentralChunk);
    std::vector<Run> bakes;
    for (int k = 0; k < o.repeat; ++k) {
        bakes.push_back(runProgram({cli.string(), "bake", space.string(), "--dry-run", "--quiet", "--chunk", kCentralChunk},
                                   dir / "bake.out", dir / "bake.err"));
        if (bakes.back().exitCode != 0 && bakes.back().exitCode != 1)
            return fail("shadowcull bake --dry-run", bakes.back(), dir / "bake.err");
    }
    res.bake = median(bakes);
    std::fprintf(stderr, "gltf_bench:   bake %.2f s, %s\n", res.bake.wall, mib(double(res.bake.maxRssKiB)).c_str());
    if (!o.keep) {
        fs::remove_all(space, ec);
        fs::remove(scene, ec);
    }

    // The memory reference: the same nodes, one mesh copy per node.
    std::fprintf(stderr, "gltf_bench:   generating the copy without instancing...\n");
    const fs::path copies = dir / "copies.glb", spaceCopies = dir / "space-copies";
    if (!generate(rocks, meshes, false, copies, res.copies, res.genCopies))
        return fail("generating the scene without instancing", res.genCopies, {});
    std::fprintf(stderr, "gltf_bench:   %s, %.1f s; importing...\n", megabytes(res.copies.fileBytes).c_str(), res.copies.genSeconds);
    res.importCopies =
        runProgram({cli.string(), "import", copies.string(), spaceCopies.string()}, dir / "import-copies.out", dir / "import-copies.err");
    if (res.importCopies.exitCode != 0) return fail("shadowcull import (no instancing)", res.importCopies, dir / "import-copies.err");
    res.spaceCopies = spaceStats(spaceCopies);
    std::fprintf(stderr, "gltf_bench:   import %.2f s, %s\n", res.importCopies.wall, mib(double(res.importCopies.maxRssKiB)).c_str());
    if (!o.keep) fs::remove_all(dir, ec);
    res.ok = true;
    return res;
}

}  // namespace

int main(int argc, char** argv) {
    const Options o = parseArgs(argc, argv);
    const fs::path self = fs::read_symlink("/proc/self/exe");
    const fs::path cli = self.parent_path() / "shadowcull";
    if (!fs::exists(cli)) {
        std::fprintf(stderr, "gltf_bench: %s not found: build the shadowcull target (it sits next to gltf_bench)\n", cli.c_str());
        return 1;
    }
    fs::create_directories(o.work);
    std::string command = "gltf_bench";
    for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];

    const std::string loadBefore = loadAverage();
    const auto t0 = std::chrono::steady_clock::now();
    // The CLI's floor: its RSS doing nothing (libraries mapped, --help printed).
    const Run floor = runProgram({cli.string(), "--help"}, o.work / "help.out", o.work / "help.err");
    std::vector<SizeResult> results;
    for (size_t k = 0; k < o.nodes.size(); ++k) results.push_back(measure(cli, o, o.nodes[k], o.meshes[k]));
    const double total = since(t0);
    const std::string loadAfter = loadAverage();
    std::error_code ec;
    fs::remove(o.work / "help.out", ec);
    fs::remove(o.work / "help.err", ec);

    // ---- Report (Markdown) ----
    std::printf("# gltf_bench\n\n");
    std::printf("`%s`: %s, %u hardware threads, %.1f GiB; load average %s before, %s after; %.0f s in all.\n"
                "Binary: %s. Each run of the real CLI is its own process (peak RSS: wait4 ru_maxrss; "
                "`shadowcull --help` alone peaks at %s).\n\n",
                command.c_str(), cpuModel().c_str(), unsigned(sysconf(_SC_NPROCESSORS_ONLN)), memTotalGiB(), loadBefore.c_str(),
                loadAfter.c_str(), total, cli.c_str(), mib(double(floor.maxRssKiB)).c_str());

    std::printf("## Scenes (seed %#llx; rocks of %d triangles in groups of %d on %.0f m ground tiles, 2 km x 2 km, 1 directional light)\n\n",
                (unsigned long long)kSeed, 20 << (2 * kSubdivisions), kGroupSize, kTile);
    std::printf("| size | nodes | mesh nodes | group nodes | unique meshes | placed triangles | .glb | generation s | .glb without instancing (unique meshes) |\n");
    std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const SizeResult& r : results) {
        std::printf("| %s / %s | %s | %s | %s | %s | %s | %s | %.1f | %s (%s) |\n", thousands(double(r.rocks)).c_str(),
                    thousands(double(r.meshes)).c_str(), thousands(double(r.scene.nodes)).c_str(), thousands(double(r.scene.meshNodes)).c_str(),
                    thousands(double(r.scene.groupNodes)).c_str(), thousands(double(r.scene.uniqueMeshes)).c_str(),
                    thousands(double(r.scene.placedTriangles)).c_str(), megabytes(r.scene.fileBytes).c_str(), r.scene.genSeconds,
                    r.ok ? megabytes(r.copies.fileBytes).c_str() : "-", r.ok ? thousands(double(r.copies.uniqueMeshes)).c_str() : "-");
    }
    std::printf("\n(size = rock nodes / unique rock meshes; mesh nodes add the ground tiles, unique meshes the tile mesh)\n\n");

    std::printf("## `shadowcull import`\n\n");
    std::printf("Median of %d runs (wall range in brackets); the import without instancing once.\n\n", o.repeat);
    std::printf("| size | wall s | CPU s (system) | wall s per 1000 mesh nodes | CPU s per 1000 mesh nodes | peak RSS | chunks | "
                "neighbours | model resources | output | peak RSS without instancing | without / with | wall s (CPU s) without "
                "instancing |\n");
    std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const SizeResult& r : results) {
        if (!r.ok && r.import.maxRssKiB == 0) {
            std::printf("| %ld / %ld | failed: %s |\n", r.rocks, r.meshes, r.failure.c_str());
            continue;
        }
        const double perK = 1000.0 / double(r.scene.meshNodes);
        std::printf("| %s / %s | %.2f (%.2f-%.2f) | %.2f (%.2f) | %.3f | %.3f | %s | %s | %d | %s | %s | %s | %s | %s |\n",
                    thousands(double(r.rocks)).c_str(), thousands(double(r.meshes)).c_str(), r.import.wall, r.import.wallMin,
                    r.import.wallMax, r.import.cpu, r.import.sys,
                    r.import.wall * perK, r.import.cpu * perK, mib(double(r.import.maxRssKiB)).c_str(),
                    thousands(double(r.space.chunks)).c_str(), r.space.neighbours, thousands(double(r.space.resources)).c_str(),
                    megabytes(r.space.bytes).c_str(), r.ok ? mib(double(r.importCopies.maxRssKiB)).c_str() : "-",
                    r.ok ? fmt("%.2fx", double(r.importCopies.maxRssKiB) / double(r.import.maxRssKiB)).c_str() : "-",
                    r.ok ? fmt("%.2f (%.2f)", r.importCopies.wall, r.importCopies.cpu).c_str() : "-");
    }
    std::printf("\n");
    for (const SizeResult& r : results)
        if (!r.failure.empty()) std::printf("- %ld / %ld: FAILED: %s\n", r.rocks, r.meshes, r.failure.c_str());

    // Memory per unique mesh (same nodes, with and without instancing) and per node
    // (between sizes, net of the unique meshes' share).
    std::printf("Memory model RSS = a + b x mesh nodes + c x unique meshes, from this run:\n\n");
    for (const SizeResult& r : results) {
        if (!r.ok) continue;
        const double du = double(r.copies.uniqueMeshes - r.scene.uniqueMeshes);
        if (du > 0)
            std::printf("- %s / %s: c = %.1f KiB per unique mesh (%.1f KiB of .glb each), from the two imports\n",
                        thousands(double(r.rocks)).c_str(), thousands(double(r.meshes)).c_str(),
                        double(r.importCopies.maxRssKiB - r.import.maxRssKiB) / du, (r.copies.fileBytes - r.scene.fileBytes) / du / 1024.0);
    }
    for (size_t k = 1; k < results.size(); ++k) {
        const SizeResult &a = results[k - 1], &b = results[k];
        if (!a.ok || !b.ok || b.scene.meshNodes == a.scene.meshNodes) continue;
        const double c = double(b.importCopies.maxRssKiB - b.import.maxRssKiB) / double(b.copies.uniqueMeshes - b.scene.uniqueMeshes);
        const double perNode = (double(b.import.maxRssKiB - a.import.maxRssKiB) - c * double(b.scene.uniqueMeshes - a.scene.uniqueMeshes)) /
                               double(b.scene.meshNodes - a.scene.meshNodes);
        std::printf("- %s -> %s mesh nodes: b = %.2f KiB per mesh node (instanced imports, net of c x the added unique meshes); "
                    "wall %.3f -> %.3f s, CPU %.3f -> %.3f s per 1000 mesh nodes\n",
                    thousands(double(a.scene.meshNodes)).c_str(), thousands(double(b.scene.meshNodes)).c_str(), perNode,
                    1000.0 * a.import.wall / double(a.scene.meshNodes), 1000.0 * b.import.wall / double(b.scene.meshNodes),
                    1000.0 * a.import.cpu / double(a.scene.meshNodes), 1000.0 * b.import.cpu / double(b.scene.meshNodes));
    }
    std::printf("\n");

    std::printf("## `shadowcull bake SPACE --dry-run --quiet --chunk %s` (one central chunk, every core)\n\n", kCentralChunk);
    std::printf("Median of %d runs (wall range in brackets).\n\n", o.repeat);
    std::printf("| size | window chunks | models in window | models in chunk | wall s | CPU s | peak RSS | exit |\n");
    std::printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const SizeResult& r : results) {
        if (r.bake.maxRssKiB == 0) continue;
        std::printf("| %s / %s | %ld | %s | %ld | %.2f (%.2f-%.2f) | %.2f | %s | %d |\n", thousands(double(r.rocks)).c_str(),
                    thousands(double(r.meshes)).c_str(), r.space.windowChunks, thousands(double(r.space.windowModels)).c_str(),
                    r.space.centreModels, r.bake.wall, r.bake.wallMin, r.bake.wallMax, r.bake.cpu, mib(double(r.bake.maxRssKiB)).c_str(),
                    r.bake.exitCode);
    }
    std::printf("\n");
    for (const SizeResult& r : results)
        if (!r.windowsLine.empty()) std::printf("- %ld / %ld: %s\n", r.rocks, r.meshes, r.windowsLine.c_str());

    double load1 = 0;
    if (getloadavg(&load1, 1) == 1 && load1 > double(sysconf(_SC_NPROCESSORS_ONLN)))
        std::printf("\nCaution: the load average (%.2f) exceeds the core count: other processes skewed these times.\n", load1);

    if (!o.jsonOut.empty()) {
        json j = {{"command", command}, {"cpu", cpuModel()}, {"threads", sysconf(_SC_NPROCESSORS_ONLN)}, {"memGiB", memTotalGiB()},
                  {"loadBefore", loadBefore}, {"loadAfter", loadAfter}, {"totalSeconds", total}, {"helpPeakRssKiB", floor.maxRssKiB},
                  {"seed", kSeed}, {"repeat", o.repeat}, {"sizes", json::array()}};
        for (const SizeResult& r : results) {
            j["sizes"].push_back({{"rockNodes", r.rocks}, {"rockMeshes", r.meshes}, {"ok", r.ok}, {"failure", r.failure},
                                  {"scene", r.scene.toJson()}, {"sceneWithoutInstancing", r.copies.toJson()},
                                  {"generate", runJson(r.gen)}, {"generateWithoutInstancing", runJson(r.genCopies)},
                                  {"import", runJson(r.import)}, {"importWithoutInstancing", runJson(r.importCopies)},
                                  {"bakeCentralChunk", runJson(r.bake)}, {"space", spaceJson(r.space)},
                                  {"spaceWithoutInstancing", spaceJson(r.spaceCopies)}, {"importLine", r.importLine},
                                  {"windowsLine", r.windowsLine}});
        }
        std::ofstream out(o.jsonOut);
        out << j.dump(1) << "\n";
        if (!out) {
            std::fprintf(stderr, "gltf_bench: could not write %s\n", o.jsonOut.c_str());
            return 1;
        }
    }
    for (const SizeResult& r : results)
        if (!r.ok) return 1;
    return 0;
}
