// Issue 17: the OpenGL backends (gpu/gl_context.h). The choice and its messages, both
// backends in one process, and the data-driven comparison: every scene (the sample space
// and a generated world) baked on every backend this machine has, by both methods, with
// every verdict compared (the CLI in a child process per bake, as a user runs it).

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bench/world_gen.h"
#include "gpu/gl_api.h"
#include "gpu/gl_context.h"
#include "io/results_file.h"
#include "tests/support/gl_available.h"
#include "tests/test_files.h"

namespace shadowcull {
namespace {

namespace fs = std::filesystem;
using testing::freshTestDir;
using testing::readText;
using testing::runCli;

// A context on `backend`, or empty with the reason in `why`.
std::unique_ptr<gpu::GlContext> contextOn(gpu::GlBackend backend, std::string& why) {
    Expected<std::unique_ptr<gpu::GlContext>> ctx = gpu::createOffscreenContext(8, 8, {backend, -1});
    if (!ctx) {
        why = ctx.error().message;
        return nullptr;
    }
    return std::move(*ctx);
}

TEST(GlBackends, NamesParseBothWays) {
    for (gpu::GlBackend b : {gpu::GlBackend::Auto, gpu::GlBackend::Egl, gpu::GlBackend::OsMesa}) {
        Expected<gpu::GlBackend> back = gpu::parseGlBackend(gpu::glBackendName(b));
        ASSERT_TRUE(back);
        EXPECT_EQ(*back, b);
    }
    Expected<gpu::GlBackend> bad = gpu::parseGlBackend("vulkan");
    ASSERT_FALSE(bad);
    EXPECT_NE(bad.error().message.find("auto, egl or osmesa"), std::string::npos) << bad.error().message;
}

TEST(GlBackends, EachBackendSaysWhatItIs) {
    REQUIRE_GL();
    std::string why;
    std::unique_ptr<gpu::GlContext> egl = contextOn(gpu::GlBackend::Egl, why);
    if (!egl) GTEST_SKIP() << "no EGL context here: " << why;
    EXPECT_EQ(egl->backend().rfind("EGL ", 0), 0u) << egl->backend();
    EXPECT_EQ(egl->description().rfind(egl->backend() + ": " + egl->vendor() + ", " + egl->renderer() + ", OpenGL ", 0), 0u)
        << egl->description();
    std::unique_ptr<gpu::GlContext> osmesa = contextOn(gpu::GlBackend::OsMesa, why);
    if (!osmesa) GTEST_SKIP() << "no OSMesa context here: " << why;
    EXPECT_EQ(osmesa->backend(), "OSMesa");
    EXPECT_EQ(osmesa->width(), 8);
    // --version lists both, and a line per EGL device.
    const std::vector<std::string> lines = gpu::listGlBackends();
    std::string all;
    for (const std::string& l : lines) all += l + "\n";
    EXPECT_NE(all.find("EGL surfaceless: "), std::string::npos) << all;
    EXPECT_NE(all.find("OSMesa: "), std::string::npos) << all;
    EXPECT_NE(all.find("EGL device"), std::string::npos) << all;
}

TEST(GlBackends, AMissingDeviceIsRefusedNotSwapped) {
    Expected<std::unique_ptr<gpu::GlContext>> ctx = gpu::createOffscreenContext(8, 8, {gpu::GlBackend::Auto, 99});
    ASSERT_FALSE(ctx);
    EXPECT_EQ(ctx.error().kind, ErrorKind::Internal);
    EXPECT_NE(ctx.error().message.find("EGL device 99"), std::string::npos) << ctx.error().message;
}

TEST(GlBackends, AutoPrefersEglAndNeverTakesTheSoftwareDeviceForAGpu) {
    REQUIRE_GL();
    std::string why;
    std::unique_ptr<gpu::GlContext> chosen = contextOn(gpu::GlBackend::Auto, why);
    ASSERT_TRUE(chosen) << why;
    // Auto: a hardware device where one works, else surfaceless, OSMesa only where
    // neither does; so auto and egl agree wherever EGL works.
    std::unique_ptr<gpu::GlContext> egl = contextOn(gpu::GlBackend::Egl, why);
    if (egl) {
        EXPECT_EQ(chosen->backend(), egl->backend());
    }
    // What auto passed over is kept for the reports: surfaceless comes after the devices.
    if (chosen->backend() == "EGL surfaceless") {
        EXPECT_EQ(chosen->passedOver().rfind("EGL device: ", 0), 0u) << chosen->passedOver();
        EXPECT_NE(chosen->report().find(" (passed over: EGL device: "), std::string::npos) << chosen->report();
    }
    // Mesa's software device (llvmpipe) is listed, but auto goes to surfaceless for it.
    for (const std::string& line : gpu::listGlBackends()) {
        if (line.find("[software]") != std::string::npos) {
            EXPECT_NE(chosen->backend(), line.substr(0, line.find(':'))) << line;
        }
    }
}

// A machine whose libEGL has no vendor (libglvnd pointed at a missing vendor file): auto
// falls through to OSMesa, --gl egl gives no context, and both say what each EGL step
// answered.
TEST(GlBackends, WithoutEglAutoFallsThroughAndSaysWhatItTried) {
    const fs::path dir = freshTestDir("gl-no-egl");
    const std::string noEgl = "__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent/egl_vendor.json SHADOWCULL_GL= ";
    auto run = [&](const std::string& args) {
        const std::string cmd = noEgl + SHADOWCULL_BIN + " " + args + " > '" + (dir / "o").string() + "' 2> '" +
                                (dir / "e").string() + "'";
        const int rc = std::system(cmd.c_str());
        return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
    };
    ASSERT_EQ(run("--version"), 0) << readText(dir / "e");
    const std::string version = readText(dir / "o");
    EXPECT_NE(version.find("  EGL surfaceless: unavailable ("), std::string::npos) << version;
    std::string why;
    const bool osmesa = contextOn(gpu::GlBackend::OsMesa, why) != nullptr;
    EXPECT_NE(version.find(osmesa ? "OpenGL: OSMesa: " : "OpenGL: none ("), std::string::npos) << version;
    if (osmesa) {
        EXPECT_NE(version.find("(passed over: EGL device: "), std::string::npos) << version;
    }
    // --gl egl: the GPU stage is skipped with a note naming both EGL steps, never OSMesa.
    const std::string space = (fs::path(SHADOWCULL_SOURCE_DIR) / "data" / "sample").string();
    ASSERT_EQ(run("bake '" + space + "' --dry-run -q --gl egl"), 0) << readText(dir / "e");
    const std::string note = readText(dir / "e");
    EXPECT_NE(note.find("gpu stage skipped: no offscreen OpenGL context: EGL device: "), std::string::npos) << note;
    EXPECT_NE(note.find("; EGL surfaceless: "), std::string::npos) << note;
    EXPECT_EQ(note.find("OSMesa"), std::string::npos) << note;
}

// Both backends alive in one process, used in turns: each context's own entry points
// while it is current (see docs/design.md, "OpenGL backends": Mesa's EGL and OSMesa share
// libglapi's dispatch, libEGL's entry points go through libglvnd's).
TEST(GlBackends, EglAndOsMesaTakeTurnsInOneProcess) {
    REQUIRE_GL();
    std::string why;
    std::unique_ptr<gpu::GlContext> egl = contextOn(gpu::GlBackend::Egl, why);
    if (!egl) GTEST_SKIP() << "no EGL context here: " << why;
    std::unique_ptr<gpu::GlContext> osmesa = contextOn(gpu::GlBackend::OsMesa, why);
    if (!osmesa) GTEST_SKIP() << "no OSMesa context here: " << why;
    gpu::GlApi eglGl, osGl;
    ASSERT_TRUE(egl->makeCurrent());
    ASSERT_TRUE(eglGl.load(*egl));
    ASSERT_TRUE(osmesa->makeCurrent());
    ASSERT_TRUE(osGl.load(*osmesa));
    // A float target per context, cleared to its own value, read back in turns.
    auto clearAndRead = [](const gpu::GlApi& gl, const gpu::RenderTarget& t, float value) {
        gl.BindFramebuffer(GL_FRAMEBUFFER, t.fbo);
        const float c[4] = {value, 0, 0, 0};
        gl.ClearBufferfv(GL_COLOR, 0, c);
        gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
        return gpu::readFloatPixels(gl, t, 0, 1, 0);
    };
    ASSERT_TRUE(egl->makeCurrent());
    Expected<gpu::RenderTarget> eglTarget = gpu::makeRenderTarget(eglGl, 4, 4, {GL_R32F}, false);
    ASSERT_TRUE(eglTarget) << eglTarget.error().message;
    ASSERT_TRUE(osmesa->makeCurrent());
    Expected<gpu::RenderTarget> osTarget = gpu::makeRenderTarget(osGl, 4, 4, {GL_R32F}, false);
    ASSERT_TRUE(osTarget) << osTarget.error().message;
    for (int round = 0; round < 3; ++round) {
        ASSERT_TRUE(egl->makeCurrent());
        for (float v : clearAndRead(eglGl, *eglTarget, 1.0f + float(round))) ASSERT_EQ(v, 1.0f + float(round));
        EXPECT_TRUE(eglGl.check("EGL turn"));
        ASSERT_TRUE(osmesa->makeCurrent());
        for (float v : clearAndRead(osGl, *osTarget, 10.0f + float(round))) ASSERT_EQ(v, 10.0f + float(round));
        EXPECT_TRUE(osGl.check("OSMesa turn"));
    }
    ASSERT_TRUE(egl->makeCurrent());
    gpu::destroyRenderTarget(eglGl, *eglTarget);
    ASSERT_TRUE(osmesa->makeCurrent());
    gpu::destroyRenderTarget(osGl, *osTarget);
}

// --- Same verdicts on every backend ------------------------------------------------------

struct SceneCase {
    std::string name;    // test name suffix
    std::string method;  // "analytic" or "gpu"
};

// "world gpu" in test names and failures, not the struct's bytes.
void PrintTo(const SceneCase& c, std::ostream* os) { *os << c.name << " " << c.method; }

// The scene's space directory: the sample as shipped, or a small generated forest world
// (bench/world_gen: terrain, trees with alpha canopies, rocks, buildings, props, three
// directional and a few local lights), written once per test process.
fs::path sceneDir(const std::string& name) {
    if (name == "sample") return fs::path(SHADOWCULL_SOURCE_DIR) / "data" / "sample";
    static const fs::path world = [] {
        const fs::path dir = freshTestDir("gl-world");
        bench::WorldSpec spec;
        spec.name = "gl-backends";
        spec.chunksX = 2, spec.chunksZ = 2;
        spec.seed = 17;
        spec.objectsPerChunk = 40;
        spec.localLights = 3;
        bench::writeWorld(spec, (dir / "world").string());
        return dir / "world";
    }();
    return world;
}

// (chunk, element, group, light) -> "bit verdict stage" of every bit of a results file.
std::map<std::string, std::string> verdictsOf(const results::ResultsFile& f) {
    std::map<std::string, std::string> out;
    for (const results::ChunkRecord& c : f.chunks)
        for (const results::ObjectRecord& o : c.objects)
            for (const results::GroupRecord& g : o.groups)
                for (const results::BitRecord& b : g.lights)
                    out[c.chunk + " element " + std::to_string(o.element) + " group " + std::to_string(g.group) +
                        " light " + std::to_string(b.light)] = std::to_string(b.bit) + " " + b.verdict + " " + b.stage;
    return out;
}

class SameVerdicts : public ::testing::TestWithParam<SceneCase> {};

TEST_P(SameVerdicts, OnEveryBackend) {
    REQUIRE_GL();
    const SceneCase& sc = GetParam();
    const fs::path space = sceneDir(sc.name);
    const fs::path dir = freshTestDir("gl-" + sc.name + "-" + sc.method);
    std::vector<std::pair<std::string, std::map<std::string, std::string>>> baked;  // backend -> verdicts
    for (const char* backend : {"egl", "osmesa"}) {
        std::string why;
        if (!contextOn(*gpu::parseGlBackend(backend), why)) {
            std::cout << "[ skipped backend " << backend << ": " << why << " ]\n";
            continue;
        }
        const fs::path results = dir / (std::string(backend) + ".json");
        const int rc = runCli("bake '" + space.string() + "' --dry-run -q --method " + sc.method + " --gl " + backend +
                                  " --results '" + results.string() + "'",
                              dir / "o", dir / "e");
        ASSERT_TRUE(rc == 0 || rc == 1) << backend << ": exit " << rc << "\n" << readText(dir / "e");
        Expected<results::ResultsFile> f = results::readResultsFile(results.string());
        ASSERT_TRUE(f) << f.error().what();
        // The GPU stages decided bits of this scene, so that a difference could show.
        const std::string gpuStage = sc.method == "gpu" ? "gpu-baseline" : "gpu";
        uint64_t byGpu = 0;
        for (const auto& [bit, verdict] : verdictsOf(*f)) byGpu += verdict.substr(verdict.rfind(' ') + 1) == gpuStage;
        EXPECT_GT(byGpu, 0u) << backend << ": no bit of " << sc.name << " was decided by the " << gpuStage << " stage";
        std::cout << "[ " << backend << ": " << byGpu << " bits decided by " << gpuStage << " ]\n";
        baked.emplace_back(backend, verdictsOf(*f));
        ASSERT_FALSE(baked.back().second.empty());
    }
    if (baked.size() < 2) GTEST_SKIP() << "fewer than two OpenGL backends here";
    // Every bit, every backend against the first: a verdict that depends on the
    // rasterizer beyond what the margins cover shows up here.
    const auto& [firstName, first] = baked[0];
    for (size_t k = 1; k < baked.size(); ++k) {
        const auto& [name, other] = baked[k];
        ASSERT_EQ(other.size(), first.size()) << name << " vs " << firstName;
        int shown = 0;
        uint64_t differ = 0;
        for (const auto& [bit, verdict] : first) {
            const std::string& o = other.at(bit);
            if (o == verdict) continue;
            ++differ;
            if (shown++ < 10) ADD_FAILURE() << bit << ": " << firstName << " " << verdict << ", " << name << " " << o;
        }
        EXPECT_EQ(differ, 0u) << "bits of " << sc.name << " (" << sc.method << ") that differ between " << firstName
                              << " and " << name;
    }
}

INSTANTIATE_TEST_SUITE_P(Scenes, SameVerdicts,
                         ::testing::Values(SceneCase{"sample", "analytic"}, SceneCase{"sample", "gpu"},
                                           SceneCase{"world", "analytic"}, SceneCase{"world", "gpu"}),
                         [](const ::testing::TestParamInfo<SceneCase>& p) { return p.param.name + "_" + p.param.method; });

}  // namespace
}  // namespace shadowcull
