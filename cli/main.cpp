// shadowcull: bakes, per object, primitive group and light, whether the shadow can matter.
// Thin: options, the pipeline (cli/pipeline.cpp), reports (cli/report.cpp).

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>

#include <CLI/CLI.hpp>

#include "cli/check.h"
#include "cli/diff.h"
#include "cli/explain.h"
#include "cli/gltf_commands.h"
#include "cli/interrupt.h"
#include "cli/merge.h"
#include "cli/output_guard.h"
#include "cli/plan.h"
#include "cli/pipeline.h"
#include "cli/preview_command.h"
#include "cli/progress_reporter.h"
#include "cli/render_command.h"
#include "cli/report.h"
#include "cli/savings_report.h"
#include "cli/shard.h"
#include "cli/sweep.h"
#include "cli/usage.h"
#include "core/limits.h"
#include "gpu/gl_context.h"
#include "gpu/render.h"
#include "util/heap_tuning.h"

using namespace shadowcull;
using namespace shadowcull::cli;

namespace {

int runPlanCommand(PlanOptions opt, bool quiet) {
    ProgressReporter progress = ProgressReporter::forStderr(!quiet);
    opt.onScanned = [&](size_t files, size_t total) { progress.scanned(files, total); };
    Expected<PlanSummary> r = makePlan(opt);
    progress.finish();
    if (!r) {
        std::fprintf(stderr, "shadowcull: error: %s\n", r.error().what().c_str());
        return exitCodeFor(r.error().kind);
    }
    for (const Diagnostic& d : r->diagnostics) std::fprintf(stderr, "shadowcull: warning: %s\n", d.what().c_str());
    if (!quiet)
        std::printf("plan: %s, %zu chunks in %d shards (a shard bakes at most %zu and reads at most %zu of them), %.1f s\n",
                    opt.planDir.c_str(), r->chunks, opt.shards, r->largestShardChunks, r->largestWindowChunks, r->seconds);
    return r->diagnostics.empty() ? kExitOk : kExitSkippedInput;
}

int runBakeCommand(BakeOptions opt, bool quiet) {
    ProgressReporter progress = ProgressReporter::forStderr(!quiet);
    opt.keepVerdicts = false;  // counted and streamed: memory follows the window
    opt.onScanned = [&](size_t files, size_t total) { progress.scanned(files, total); };
    Expected<BakeResult> r = runBake(opt, [&](const BakeProgress& p) { progress.baked(p); });
    progress.finish();
    if (!r) {
        // The message ends by saying which chunk files, if any, were updated.
        std::fprintf(stderr, "shadowcull: error: %s\n", r.error().what().c_str());
        return exitCodeFor(r.error().kind);
    }
    for (const Diagnostic& d : r->diagnostics) std::fprintf(stderr, "shadowcull: warning: %s\n", d.what().c_str());
    for (const std::string& n : r->notes) std::fprintf(stderr, "shadowcull: note: %s\n", n.c_str());
    if (!quiet) std::fputs(formatSummary(*r, opt.write).c_str(), stdout);
    return r->diagnostics.empty() ? kExitOk : kExitSkippedInput;
}

// --gl / --gl-device: the OpenGL backend of the GPU stages, for the commands that run
// them. Starts from SHADOWCULL_GL / SHADOWCULL_GL_DEVICE (gpu::glChoice()).
struct GlFlags {
    std::string backend = gpu::glBackendName(gpu::glChoice().backend);
    int device = gpu::glChoice().device;
};

void addGlOptions(CLI::App* command, GlFlags& flags) {
    command->add_option("--gl", flags.backend,
                        "OpenGL backend of the GPU stages: auto (default: an EGL GPU device, then EGL surfaceless, "
                        "then OSMesa), egl or osmesa")
        ->check(oneOf({"auto", "egl", "osmesa"}));
    command->add_option("--gl-device", flags.device, "EGL device to render on (numbered as 'shadowcull --version' lists them)")
        ->check(atLeast(0));
}

// A subcommand: its options, parsed into state it owns, and what it runs.
struct Command {
    CLI::App* app;
    std::function<int()> run;
};

// The commands that stage what they write stop between steps and remove it; the others
// only read, or write one file atomically at their end, and end at once.
void stopBetweenSteps() { setInterruptMode(InterruptMode::StopBetweenSteps); }

Command bakeCommand(CLI::App& app, GlFlags& gl) {
    struct State {
        BakeOptions opt;
        bool quiet = false;
        std::vector<std::string> stageNames{"raycast", "geometry", "gpu"};
        std::string method = "analytic", shardText;
    };
    auto st = std::make_shared<State>();
    BakeOptions& opt = st->opt;
    CLI::App* bake = app.add_subcommand("bake", "Bake the <shadow> masks of a space's chunk files");
    bake->add_option("space", opt.spaceDir, "Space directory (holds space.xml and *.chunk)")->required()->check(existingDirectory());
    bake->footer(kBakeExitCodes);
    bake->add_option("--out", opt.outDir, "Write baked copies of the chunk files here instead of in place");
    bake->add_option("--res", opt.resourceRoot, "Resource root (default: <resourceRoot> of space.xml, else the space)");
    bake->add_option("--chunk", opt.chunkNames, "Bake only these chunks (XXXXZZZZo or XXXXZZZZo.chunk); repeatable");
    bake->add_option("--threads", opt.threads, "Worker threads (default, or 0: all cores)")->check(atLeast(0));
    bake->add_option("--results", opt.resultsPath, "Write per-bit verdicts and evidence as JSON");
    bake->add_flag("--force-write", opt.forceWrite,
                   "Also replace chunk files that are read-only or whose owner and group cannot be kept");
    bake->add_option("--samples", opt.raycast.areaSamples, "Area samples per group and light for witness rays")
        ->check(within(1, 1 << 20))
        ->capture_default_str();
    bake->add_option("--receiver-samples", opt.raycast.receiverSamples,
                     "Points on the receivers in a large caster's shadow (terrain...) per bit its own samples leave "
                     "undecided (0: off)")
        ->check(within(0, 1 << 20))
        ->capture_default_str();
    bake->add_option("--stages", st->stageNames, "Stages after the input/reach checks (default: raycast,geometry,gpu)")
        ->delimiter(',')
        ->check(oneOf({"raycast", "geometry", "gpu"}));
    bake->add_option("--method", st->method,
                     "analytic (default, conservative) or gpu (the original stencil + occlusion-query method: a baseline, "
                     "NOT conservative)")
        ->check(oneOf({"analytic", "gpu"}));
    bake->add_option("--gpu-resolution", opt.gpuResolution, "Pixels per side of each light view (GPU stages)")
        ->check(within(16, 16384))
        ->capture_default_str();
    bake->add_flag("--gpu-terrain", opt.gpuTerrain,
                   "Also send terrain groups to the GPU confirmation (slow; they are rarely proved there)");
    bake->add_option("--gpu-close-up", opt.gpuCloseUpResolution,
                     "Pixels per side of the GPU confirmation's second look, each directional view framed on the "
                     "casters still undecided (0: none; at most --gpu-resolution)")
        ->check(within(0, 16384))
        ->capture_default_str();
    bake->add_flag("--dry-run", [&opt](int64_t) { opt.write = false; }, "Compute and report, but write no chunk file");
    bake->add_flag("--quiet,-q", st->quiet, "No progress bar and no summary");
    bake->add_flag("--resume", opt.resume,
                   "Long bakes: commit each chunk when baked; skip chunks unchanged since the last --resume bake");
    bake->add_option("--shard", st->shardText,
                     "Bake only part K of N of the space (K from 1; own lock, resume state and results; join the results with "
                     "'merge')")
        ->check(CLI::Validator(
            [](std::string& v) { return parseShard(v) ? std::string() : "expected K/N with 1 <= K <= N <= " + std::to_string(kMaxShards); },
            "K/N"));
    bake->add_option("--plan", opt.planDir,
                     "With --shard: the plan 'shadowcull plan' wrote; the shard reads it and only the chunks its windows "
                     "hold (exit 9 if the space changed since)")
        ->check(existingDirectory());
    addGlOptions(bake, gl);
    return {bake, [st] {
                BakeOptions& opt = st->opt;
                auto chosen = [&](const char* stage) {
                    return std::find(st->stageNames.begin(), st->stageNames.end(), stage) != st->stageNames.end();
                };
                opt.raycast.threads = opt.threads;
                opt.useRaycast = chosen("raycast");
                opt.useGeometry = chosen("geometry");
                opt.useGpu = chosen("gpu");
                opt.gpuBaseline = st->method == "gpu";
                opt.witnessBaselineCulls = opt.gpuBaseline;  // the note says how many 0s have a witness
                if (std::optional<ShardSpec> shard = parseShard(st->shardText)) opt.shardIndex = shard->index, opt.shardCount = shard->count;
                if (!opt.planDir.empty() && opt.shardCount == 0) {
                    std::fprintf(stderr, "shadowcull bake: --plan is a sharded bake's plan: give --shard K/N too\n");
                    return int(kExitUsage);
                }
                if (opt.shardCount > 0 && !opt.chunkNames.empty()) {
                    std::fprintf(stderr, "shadowcull bake: --shard bakes a part of the whole space; it cannot be combined with --chunk\n");
                    return int(kExitUsage);
                }
                stopBetweenSteps();
                return runBakeCommand(opt, st->quiet);
            }};
}

Command sweepCommand(CLI::App& app, GlFlags& gl) {
    struct State {
        SweepOptions opt;
        bool noGpu = false;
    };
    auto st = std::make_shared<State>();
    SweepOptions& sweepOpt = st->opt;
    CLI::App* sweep = app.add_subcommand("sweep", "What accuracy costs in time: a ladder of settings against a dense reference");
    sweep->add_option("space", sweepOpt.spaceDir, "Space directory")->required()->check(existingDirectory());
    sweep->footer(kReportExitCodes);
    sweep->add_option("--res", sweepOpt.resourceRoot, "Resource root");
    sweep->add_option("--csv", sweepOpt.csvPath, "Write the table as CSV");
    sweep->add_option("--svg", sweepOpt.svgPath, "Write a plot of false keeps against seconds (SVG)");
    sweep->add_option("--threads", sweepOpt.threads, "Worker threads (default, or 0: all cores)")->check(atLeast(0));
    sweep->add_option("--reference-samples", sweepOpt.referenceSamples, "Area samples of the reference bake")
        ->check(within(1, 1 << 20))
        ->capture_default_str();
    sweep->add_flag("--quick", sweepOpt.quick, "A shorter ladder");
    sweep->add_flag("--no-gpu", st->noGpu, "Leave out the GPU settings");
    addGlOptions(sweep, gl);
    return {sweep, [st] {
                stopBetweenSteps();
                SweepOptions& sweepOpt = st->opt;
                std::vector<SweepSetting> ladder = analyticLadder(sweepOpt.quick);
                if (st->noGpu) ladder.erase(std::remove_if(ladder.begin(), ladder.end(), [](const SweepSetting& s) { return s.name.find("gpu") != std::string::npos || s.name.find("GPU") != std::string::npos; }), ladder.end());
                else
                    for (SweepSetting& s : gpuBaselineLadder(sweepOpt.quick)) ladder.push_back(std::move(s));
                sweepOpt.progress = &std::cerr;
                Expected<std::vector<SweepRow>> rows = runSweep(sweepOpt, ladder);
                if (!rows) {
                    std::fprintf(stderr, "shadowcull: error: %s\n", rows.error().what().c_str());
                    return exitCodeFor(rows.error().kind);
                }
                return reportSweep(sweepOpt, *rows, std::cout, std::cerr);
            }};
}

Command diffCommand(CLI::App& app) {
    auto diffOpt = std::make_shared<DiffOptions>();
    CLI::App* diff = app.add_subcommand("diff", "Bits that changed between two bakes (results JSON files or baked spaces)");
    diff->add_option("old", diffOpt->oldPath, "Old results JSON or baked space")->required()->check(existingPath());
    diff->footer(kDiffExitCodes);
    diff->add_option("new", diffOpt->newPath, "New results JSON or baked space")->required()->check(existingPath());
    diff->add_option("--html", diffOpt->htmlPath, "Write a self-contained HTML report");
    diff->add_option("--json", diffOpt->jsonPath, "Write the changes as JSON");
    return {diff, [diffOpt] { return runDiff(*diffOpt, std::cout, std::cerr); }};
}

Command explainCommand(CLI::App& app) {
    auto explainOpt = std::make_shared<ExplainOptions>();
    CLI::App* explain = app.add_subcommand("explain", "Why each bit of one object is what it is");
    explain->add_option("space", explainOpt->spaceDir, "Space directory")->required()->check(existingDirectory());
    explain->footer(kReportExitCodes);
    explain->add_option("chunk", explainOpt->chunk, "Chunk (XXXXZZZZo or XXXXZZZZo.chunk)")->required();
    explain->add_option("object", explainOpt->object, "Object: uuid, or element index")->required();
    explain->add_option("--res", explainOpt->resourceRoot, "Resource root");
    explain->add_option("--light", explainOpt->light, "Only this light (1-based; default: every light)")->check(atLeast(1));
    return {explain, [explainOpt] { return runExplain(*explainOpt, std::cout, std::cerr); }};
}

Command checkCommand(CLI::App& app, GlFlags& gl) {
    auto checkOpt = std::make_shared<CheckOptions>();
    CLI::App* check = app.add_subcommand("check", "Cross-check the original GPU method against the analytic pipeline");
    check->add_option("space", checkOpt->spaceDir, "Space directory")->required()->check(existingDirectory());
    check->footer(kCheckExitCodes);
    check->add_option("--res", checkOpt->resourceRoot, "Resource root");
    check->add_option("--gpu-resolution", checkOpt->gpuResolution, "Pixels per side of each light view")
        ->check(within(16, 16384))
        ->capture_default_str();
    check->add_option("--pictures", checkOpt->outDir, "Directory for the light-view pictures (default: shadowcull-check)");
    check->add_option("--threads", checkOpt->threads, "Worker threads (default, or 0: all cores)")->check(atLeast(0));
    addGlOptions(check, gl);
    return {check, [checkOpt] {
                stopBetweenSteps();
                return runCheck(*checkOpt, std::cout, std::cerr);
            }};
}

Command renderCommand(CLI::App& app, GlFlags& gl) {
    struct State {
        BakeOptions opt;
        std::string chunk, out, method = "analytic";
        int light = 1;
    };
    auto st = std::make_shared<State>();
    CLI::App* render = app.add_subcommand("render", "Write a light's view of a chunk window, coloured by verdict (PNG)");
    render->add_option("space", st->opt.spaceDir, "Space directory")->required()->check(existingDirectory());
    render->footer(kReportExitCodes);
    render->add_option("--chunk", st->chunk, "Chunk (XXXXZZZZo or XXXXZZZZo.chunk)")->required();
    render->add_option("--light", st->light, "Light (1-based, as in space.xml)")->required()->check(atLeast(1));
    render->add_option("--out", st->out, "PNG file")->required();
    render->add_option("--res", st->opt.resourceRoot, "Resource root");
    render->add_option("--gpu-resolution", st->opt.gpuResolution, "Pixels per side")->check(within(16, 16384))->capture_default_str();
    render->add_option("--method", st->method, "Colour by the analytic verdicts (default) or the GPU method's")
        ->check(oneOf({"analytic", "gpu"}));
    addGlOptions(render, gl);
    return {render, [st] {
                stopBetweenSteps();
                RenderOptions ro{st->opt, st->chunk, st->out, st->light};
                ro.bake.gpuBaseline = st->method == "gpu";
                return runRender(ro, std::cout, std::cerr);
            }};
}

Command previewCommand(CLI::App& app) {
    auto previewOpt = std::make_shared<PreviewOptions>();
    CLI::App* preview = app.add_subcommand("preview", "Render a camera view shadowed as an engine does, with every caster and with the kept ones (PNG)");
    preview->add_option("space", previewOpt->bake.spaceDir, "Space directory")->required()->check(existingDirectory());
    preview->footer(kPreviewExitCodes);
    preview->add_option("--chunk", previewOpt->chunk, "Chunk (XXXXZZZZo or XXXXZZZZo.chunk)")->required();
    preview->add_option("--light", previewOpt->light, "Light (1-based, as in space.xml)")->required()->check(atLeast(1));
    preview->add_option("--camera", previewOpt->camera, "EYE_X,EYE_Y,EYE_Z,TARGET_X,TARGET_Y,TARGET_Z in world metres (default: the chunk from above)");
    preview->add_option("--shadow-resolution", previewOpt->shadowResolution, "Texels per side of each shadow-map view")
        ->check(within(16, 8192))
        ->capture_default_str();
    preview->add_option("--pcf-radius", previewOpt->pcfRadius, "PCF radius in texels (default: the largest whose footprint fits the light's filterRadius)")
        ->check(within(0, 8));
    preview->add_option("--out", previewOpt->outPath, "PNG file")->capture_default_str();
    preview->add_option("--res", previewOpt->bake.resourceRoot, "Resource root");
    return {preview, [previewOpt] {
                stopBetweenSteps();
                return runPreview(*previewOpt, std::cout, std::cerr);
            }};
}

Command importCommand(CLI::App& app) {
    struct State {
        gltf::ImportOptions opt;
        std::string sun;
    };
    auto st = std::make_shared<State>();
    gltf::ImportOptions& importOpt = st->opt;
    CLI::App* import = app.add_subcommand("import", "Turn a glTF 2.0 scene (nodes, meshes, KHR_lights_punctual) into a space");
    import->add_option("scene", importOpt.scenePath, "Scene (.gltf or .glb)")->required()->check(existingFile());
    import->footer(kImportExitCodes);
    import->add_option("out", importOpt.outDir, "New space directory (must not exist, or be empty)")->required();
    import->add_option("--scene", importOpt.scene, "Scene index (default: the file's default scene)")->check(atLeast(0));
    import->add_option("--sun", st->sun, "Add a directional light: AZIMUTH,ELEVATION in degrees (azimuth 0 = -Z, 90 = +X)");
    import->add_option("--bias", importOpt.bias, "Shadow bias of every light, metres (a light node's extras.shadowcull_bias overrides)")
        ->check(within(0.0, 1e5, false))
        ->capture_default_str();
    import->add_option("--slope-bias", importOpt.slopeBias, "Slope bias of every light, metres at 45 degrees")
        ->check(within(0.0, 1e5, false))
        ->capture_default_str();
    import->add_option("--filter-radius", importOpt.filterRadius, "Filter radius of every light, metres")
        ->check(within(0.0, 1e5, false))
        ->capture_default_str();
    import->add_option("--normal-bias", importOpt.normalBias,
                       "Normal bias of every light, metres along the receiver's normal (three.js normalBias)")
        ->check(within(0.0, 1e5, false))
        ->capture_default_str();
    import->add_option("--chunk-size", importOpt.chunkSize, "Chunk side in metres (default 64)")
        ->check(within(limits::kMinChunkSize, limits::kMaxChunkSize, false));
    import->add_option("--neighbours", importOpt.neighbours, "Chunks loaded on each side of a baked chunk (default: chosen, see docs)")
        ->check(within(0, 64));
    import->add_option("--light-cutoff", importOpt.lightCutoffLux,
                       "Lux at which a point or spot light without range ends")
        ->check(positiveNumber())
        ->capture_default_str();
    return {import, [st] {
                stopBetweenSteps();
                return runImport(st->opt, st->sun, std::cout, std::cerr);
            }};
}

Command exportCommand(CLI::App& app) {
    auto exportOpt = std::make_shared<gltf::ExportOptions>();
    CLI::App* exportCmd = app.add_subcommand("export", "Write a bake's masks into a copy of the imported glTF scene (extras.shadowcull)");
    exportCmd->add_option("space", exportOpt->spaceDir, "Space written by import")->required()->check(existingDirectory());
    exportCmd->footer(kExportExitCodes);
    exportCmd->add_option("results", exportOpt->resultsPath, "Results JSON of a bake of that space")->required()->check(existingFile());
    exportCmd->add_option("--gltf", exportOpt->scenePath, "The scene the space was imported from")->required()->check(existingFile());
    exportCmd->add_option("--out", exportOpt->outPath, "The copy to write (.glb for a .glb scene, .gltf for a .gltf scene)")->required();
    return {exportCmd, [exportOpt] { return runExport(*exportOpt, std::cout, std::cerr); }};
}

Command reportCommand(CLI::App& app) {
    auto reportOpt = std::make_shared<ReportOptions>();
    CLI::App* report = app.add_subcommand("report", "What a bake's masks remove from each light's shadow pass (casters, triangles)");
    report->add_option("space", reportOpt->spaceDir, "The space that was baked")->required()->check(existingDirectory());
    report->footer(kSavingsExitCodes);
    report->add_option("results", reportOpt->resultsPath, "Results JSON of the bake (bake --results)")->required()->check(existingFile());
    report->add_option("--html", reportOpt->htmlPath, "Write a self-contained HTML page (maps, tables, biggest savings)");
    report->add_option("--res", reportOpt->resourceRoot, "Resource root");
    return {report, [reportOpt] { return runReport(*reportOpt, std::cout, std::cerr); }};
}

Command planCommand(CLI::App& app) {
    struct State {
        PlanOptions opt;
        bool quiet = false;
    };
    auto st = std::make_shared<State>();
    PlanOptions& opt = st->opt;
    CLI::App* plan = app.add_subcommand("plan", "Scan a space once and partition it for a sharded bake (bake --shard K/N --plan DIR)");
    plan->add_option("space", opt.spaceDir, "Space directory (holds space.xml and *.chunk)")->required()->check(existingDirectory());
    plan->footer(kPlanExitCodes);
    plan->add_option("--shards", opt.shards, "How many shards (N of bake --shard K/N)")
        ->required()
        ->check(within(1, kMaxShards));
    plan->add_option("--plan", opt.planDir, "Directory to write the plan into (plan.json, shard-K-of-N.json)")->required();
    plan->add_option("--res", opt.resourceRoot, "Resource root (default: <resourceRoot> of space.xml, else the space)");
    plan->add_option("--threads", opt.threads, "Worker threads (default, or 0: all cores)")->check(atLeast(0));
    plan->add_flag("--quiet,-q", st->quiet, "No progress and no summary");
    return {plan, [st] {
                stopBetweenSteps();
                return runPlanCommand(st->opt, st->quiet);
            }};
}

Command mergeCommand(CLI::App& app) {
    auto mergeOpt = std::make_shared<MergeOptions>();
    CLI::App* merge = app.add_subcommand("merge", "Join the results files of the shards of one bake (bake --shard K/N --results)");
    merge->add_option("out", mergeOpt->outPath, "Merged results JSON to write")->required();
    merge->footer(kMergeExitCodes);
    merge->add_option("shards", mergeOpt->shardPaths, "Every shard's results JSON")->required()->check(existingFile());
    return {merge, [mergeOpt] { return runMerge(*mergeOpt, std::cout, std::cerr); }};
}

}  // namespace

int main(int argc, char** argv) {
    // First: a signal while the process starts ends it with 128 + signal and a message, not
    // with the default action's silence. Once the command is known, those that stage their
    // outputs take signals between steps (stopBetweenSteps).
    installInterruptHandlers(InterruptMode::ExitAtOnce);
    shadowcull::tuneHeapForLongBakes();
    // Named here, not after argv[0], so that --help reads the same however it was started.
    CLI::App app{"shadowcull: bakes which shadow casters matter, per object, primitive group and light", "shadowcull"};
    app.require_subcommand(1);
    app.failure_message(formatParseFailure);
    app.set_version_flag("--version", versionText, "Print the versions of shadowcull, its libraries and the OpenGL renderer");
    app.footer(kTopFooter);

    // In the order --help lists them.
    GlFlags glFlags;
    const std::vector<Command> commands{bakeCommand(app, glFlags),  sweepCommand(app, glFlags),  diffCommand(app),
                                        explainCommand(app),        checkCommand(app, glFlags),  renderCommand(app, glFlags),
                                        previewCommand(app),        importCommand(app),          exportCommand(app),
                                        reportCommand(app),         planCommand(app),            mergeCommand(app)};
    try {
        app.parse(argc, argv);
    } catch (const CLI::Success& e) {  // --help, --version
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return kExitUsage;
    }
    if (glFlags.backend == "osmesa" && glFlags.device >= 0) {
        std::fputs(formatParseFailure(&app, CLI::ValidationError("--gl-device", "names an EGL device; --gl osmesa has none")).c_str(), stderr);
        return kExitUsage;
    }
    gpu::setGlChoice({*gpu::parseGlBackend(glFlags.backend), glFlags.device});
    for (const Command& c : commands)
        if (*c.app) return c.run();
    return kExitUsage;
}
