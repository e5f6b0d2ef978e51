// Issue 16: a bake's memory follows its window, not the world. The space is scanned once,
// chunks are loaded when a window needs them and dropped when no window will, and the
// results file is streamed a chunk at a time: the verdicts, the warnings and the bytes
// written must be those of a bake that holds everything.

#include <algorithm>
#include <chrono>
#include <cstring>
#include <set>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "bench/world_gen.h"
#include "cli/pipeline.h"
#include "cli/report.h"
#include "cli/resume.h"
#include "core/window_plan.h"
#include "io/chunk_writer.h"
#include "io/results_file.h"
#include "io/scene_reader.h"
#include "io/space_source.h"
#include "raycast/group_samples.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

const fs::path kSample = fs::path(SHADOWCULL_SOURCE_DIR) / "data" / "sample";

// 6 x 5 chunks of the benchmark forest, thinned: a terrain per chunk (so heightfields and
// their meshes come and go as the window slides), trees, rocks, buildings, local lights.
std::string writeStripWorld(const fs::path& dir, int chunksX = 6) {
    bench::WorldSpec w;
    w.name = "lazy-test";
    w.chunksX = chunksX, w.chunksZ = 5;
    w.seed = 1616;
    w.objectsPerChunk = 16;
    w.terrainSamples = 9;
    w.localLights = 3;
    const fs::path space = dir / "space";
    bench::writeWorld(w, space.string());
    return space.string();
}

cli::BakeOptions quickBake(const std::string& space) {
    cli::BakeOptions opt;
    opt.spaceDir = space;
    opt.write = false;
    opt.useGpu = false;
    opt.raycast.areaSamples = 8;
    return opt;
}

// verdict + stage of every bit of a chunk, in order.
std::vector<std::string> codes(const ChunkVerdicts& cv) {
    std::vector<std::string> s;
    for (const ObjectVerdicts& ov : cv.objects)
        for (const Decision& d : ov.decisions) s.push_back(verdictName(d.verdict) + std::string(":") + std::string(d.stage));
    return s;
}

// "" when equal, else where they first differ.
std::string firstDifference(const std::vector<std::string>& a, const std::vector<std::string>& b) {
    if (a.size() != b.size()) return std::to_string(a.size()) + " bits against " + std::to_string(b.size());
    for (size_t k = 0; k < a.size(); ++k)
        if (a[k] != b[k]) return "bit " + std::to_string(k) + ": " + a[k] + " against " + b[k];
    return {};
}

// Loads every chunk of `source` until one fails: the failure must be the Io error naming
// `file` as changed on disk since the scan.
void expectLoadingRefuses(SpaceSource& source, const std::string& file) {
    Space lazy;
    std::vector<Diagnostic> late;
    bool failed = false;
    for (const auto& [c, entry] : source.chunks())
        if (Status s = source.load(c, lazy, late); !s) {
            failed = true;
            EXPECT_NE(s.error().what().find(file + ": changed on disk while the bake ran"), std::string::npos) << s.error().what();
            break;
        }
    EXPECT_TRUE(failed);
}

// A copy of the sample with bad resources: the trees' material missing, the chunk
// ffffffffo's rock_a renamed to a model that does not exist. Returns the space.
fs::path sampleWithBadResources(const fs::path& dir) {
    fs::copy(kSample, dir / "space", fs::copy_options::recursive);
    const fs::path space = dir / "space";
    fs::remove(space / "models/tree.mtl");
    std::string text = readText(space / "ffffffffo.chunk");
    text.replace(text.find("models/rock_a"), 13, "models/nope");
    writeText(space / "ffffffffo.chunk", text);
    return space;
}

}  // namespace

// The scan says what loadSpace says (warnings in its order, input files), and a chunk loaded
// lazily is the chunk loadSpace reads: same objects, skipped alike, same mesh content.
TEST(SpaceSource, LazyChunksAreTheChunksLoadSpaceReads) {
    // A bad resource shared by many objects, a missing one, a bad name, a singular transform.
    const fs::path space = sampleWithBadResources(freshTestDir());
    writeText(space / "zz.chunk", "<chunk/>\n");

    Expected<Space> eager = loadSpace(space.string(), "");
    ASSERT_TRUE(eager) << eager.error().what();
    Expected<SpaceSource> source = SpaceSource::scan(space.string(), "");
    ASSERT_TRUE(source) << source.error().what();
    ASSERT_GE(eager->diagnostics.size(), 4u);
    ASSERT_EQ(source->diagnostics().size(), eager->diagnostics.size());
    for (size_t k = 0; k < eager->diagnostics.size(); ++k)
        EXPECT_EQ(source->diagnostics()[k].what(), eager->diagnostics[k].what());
    // Every input loadSpace names is one the bake never writes over.
    const std::vector<std::string> inputs = source->inputFiles();
    for (const std::string& f : eager->inputFiles()) EXPECT_TRUE(std::binary_search(inputs.begin(), inputs.end(), f)) << f;
    ASSERT_EQ(source->chunks().size(), eager->chunks.size());

    Space lazy;
    std::vector<Diagnostic> late;
    for (const auto& [c, entry] : source->chunks()) {
        ASSERT_TRUE(source->load(c, lazy, late)) << chunkFileName(c);
        const ChunkFile& a = eager->chunks.at(c);
        const ChunkFile& b = lazy.chunks.at(c);
        EXPECT_EQ(a.contentHash, b.contentHash);
        ASSERT_EQ(a.objects.size(), b.objects.size());
        for (size_t k = 0; k < a.objects.size(); ++k) {
            const ChunkObject &x = a.objects[k], &y = b.objects[k];
            EXPECT_EQ(x.skipped, y.skipped) << b.path << " #" << k;
            EXPECT_EQ(x.skipReason, y.skipReason);
            ASSERT_EQ(bool(x.mesh), bool(y.mesh));
            ASSERT_EQ(bool(x.heightfield), bool(y.heightfield));
            if (x.mesh) {
                EXPECT_EQ(contentHash(*x.mesh), contentHash(*y.mesh));
            }
            if (x.heightfield) {
                EXPECT_EQ(contentHash(*x.heightfield), contentHash(*y.heightfield));
            }
        }
    }
    EXPECT_TRUE(late.empty()) << "nothing was edited";
    // Unloading everything lets every mesh and heightfield go.
    TerrainMeshes terrainMeshes;
    for (const auto& [c, entry] : source->chunks()) source->unload(c, lazy, terrainMeshes);
    EXPECT_EQ(source->liveResources(), 0u);
}

// The resources a chunk uses first are loaded in parallel, and judged in object order: a
// chunk with several bad ones (a missing material, a missing OBJ, a malformed one) gets the
// same diagnostics in the same order on one thread as on two, and the same summaries.
TEST(SpaceSource, FirstUsesLoadedInParallelAreReportedInObjectOrder) {
    const fs::path space = sampleWithBadResources(freshTestDir());
    writeText(space / "models/rock_b.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
    const std::string text = readText(space / "ffffffffo.chunk");
    auto scan = [&](int threads) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
        Expected<SpaceSource> source = SpaceSource::scan(space.string(), "");
        EXPECT_TRUE(source) << source.error().what();
        std::vector<std::string> said;
        if (source)
            for (const Diagnostic& d : source->diagnostics()) said.push_back(d.what());
        return said;
    };
    const std::vector<std::string> one = scan(1), two = scan(2);
    EXPECT_EQ(one, two);
    auto at = [&](const std::string& what) {
        for (size_t k = 0; k < two.size(); ++k)
            if (two[k].find(what) != std::string::npos) return int(k);
        return -1;
    };
    const int tree = at("tree.mtl"), nope = at("models/nope.obj"), rock = at("rock_b.obj:4");
    ASSERT_GE(tree, 0);
    ASSERT_GE(nope, 0);
    ASSERT_GE(rock, 0);
    // ffffffffo.chunk names the rock_a (now nope) before rock_b, and both before the trees.
    EXPECT_LT(text.find("models/nope"), text.find("models/rock_b"));
    EXPECT_LT(nope, rock);
}

// A resource edited while the bake runs is not silently used in place of what the scan read.
// A mesh's content hash (hashed a word at a time) changes with any one bit of a vertex
// coordinate, any index, the group of any triangle, the order of two triangles, and the
// group flags; equal meshes hash equal.
TEST(SpaceSource, AMeshsContentHashSeesEveryChange) {
    Mesh m;
    for (int k = 0; k < 40; ++k) m.positions.push_back({0.1 * k, 0.25 * (k % 3), -0.5 * k});
    for (uint32_t k = 0; k + 2 < 40; ++k) {
        m.triangles.push_back({k, k + 1, k + 2});
        m.triangleGroup.push_back(k % 2);
    }
    m.groups.resize(2);
    const uint64_t base = contentHash(m);
    EXPECT_EQ(contentHash(Mesh(m)), base);
    std::set<uint64_t> seen{base};
    auto changed = [&](const Mesh& x, const std::string& what) { EXPECT_TRUE(seen.insert(contentHash(x)).second) << what; };
    for (int axis = 0; axis < 3; ++axis)
        for (int bit : {0, 31, 52, 63}) {
            Mesh x = m;
            uint64_t w;
            std::memcpy(&w, &x.positions[17][axis], sizeof w);
            w ^= uint64_t(1) << bit;
            std::memcpy(&x.positions[17][axis], &w, sizeof w);
            changed(x, "bit " + std::to_string(bit) + " of axis " + std::to_string(axis));
        }
    for (int c = 0; c < 3; ++c) {
        Mesh x = m;
        x.triangles[5][size_t(c)] ^= 1;
        changed(x, "index " + std::to_string(c));
    }
    Mesh regrouped = m;
    regrouped.triangleGroup[9] ^= 1;
    changed(regrouped, "a triangle's group");
    Mesh swapped = m;
    std::swap(swapped.triangles[3], swapped.triangles[4]);
    std::swap(swapped.triangleGroup[3], swapped.triangleGroup[4]);
    changed(swapped, "two triangles swapped");
    Mesh flagged = m;
    flagged.groups[1].alphaTested = true;
    changed(flagged, "a group's alpha test");
    Mesh mirrored = m;  // two sign bits: a multiply-only word hash cancelled them
    mirrored.positions[3].x = -mirrored.positions[3].x;
    mirrored.positions[30].z = -mirrored.positions[30].z;
    changed(mirrored, "two coordinates' signs");
}

TEST(SpaceSource, AResourceChangedSinceTheScanIsAnError) {
    const fs::path dir = freshTestDir();
    fs::copy(kSample, dir / "space", fs::copy_options::recursive);
    Expected<SpaceSource> source = SpaceSource::scan((dir / "space").string(), "");
    ASSERT_TRUE(source);
    writeText(dir / "space/models/rock_a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    expectLoadingRefuses(*source, "rock_a.obj");
}

namespace {

// The sample copied, every file dated an hour back (as a space at rest is).
fs::path restingSample(const fs::path& dir) {
    fs::copy(kSample, dir / "space", fs::copy_options::recursive);
    const auto past = fs::file_time_type::clock::now() - std::chrono::hours(1);
    for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir / "space"))
        if (e.is_regular_file()) fs::last_write_time(e.path(), past);
    return dir / "space";
}

}  // namespace

// The meshes the scan parsed are kept for the windows (issue 13: parsing world D's 13 MB of
// OBJ twice was a tenth of its bake) and handed over once each, the same content.
TEST(SpaceSource, TheScansMeshesGoToTheFirstWindowsThatNeedThem) {
    const fs::path space = restingSample(freshTestDir());
    Expected<SpaceSource> source = SpaceSource::scan(space.string(), "");
    ASSERT_TRUE(source);
    const size_t parked = source->parkedMeshes();
    EXPECT_GT(parked, 3u);
    Expected<Space> whole = loadSpace(space.string(), "");
    ASSERT_TRUE(whole);
    Space lazy;
    std::vector<Diagnostic> late;
    for (const auto& [c, entry] : source->chunks()) ASSERT_TRUE(source->load(c, lazy, late));
    EXPECT_EQ(source->parkedMeshes(), 0u);
    for (const auto& [c, cf] : whole->chunks)
        for (size_t k = 0; k < cf.objects.size(); ++k) {
            const ChunkObject &a = cf.objects[k], &b = lazy.chunks.at(c).objects[k];
            ASSERT_EQ(bool(a.mesh), bool(b.mesh));
            if (a.mesh) {
                EXPECT_EQ(contentHash(*a.mesh), contentHash(*b.mesh));
            }
        }
}

// A window's new chunk files read ahead (during the previous window's bake, on a thread of
// their own) load as read when the window is entered: the same chunks, objects and
// late warnings as a sequence that reads each at its window, also with a chunk edited
// since the scan (its warnings come late) and with read-aheads meant for a window that is
// then not the next one (they are dropped, the chunks read then).
TEST(SpaceSource, ChunksReadAheadLoadAsReadAtTheirWindow) {
    const fs::path dir = freshTestDir();
    const std::string space = writeStripWorld(dir, 8);
    Expected<SpaceSource> scanned = SpaceSource::scan(space, "");
    ASSERT_TRUE(scanned);
    // An edit since the scan: an object's resource now a malformed OBJ.
    writeText(fs::path(space) / "models" / "bad_new.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
    const ChunkCoord edited{3, 2};
    const std::string path = scanned->chunks().at(edited).path;
    const std::string original = readText(path);
    std::string text = original;
    const size_t at = text.find("<resource> models/");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, text.find("</resource>", at) - at, "<resource> models/bad_new.obj ");
    std::vector<ChunkCoord> centres;
    for (const auto& [c, e] : scanned->chunks()) centres.push_back(c);
    const WindowPlanner planner(scanned->settings(), scanned->chunks(), true);
    struct Run {
        std::vector<std::string> loaded;  // per window: its chunks, objects and skips
        std::vector<std::string> late;
    };
    auto run = [&](bool ahead) {
        writeText(path, original);
        Expected<SpaceSource> source = SpaceSource::scan(space, "");
        EXPECT_TRUE(source);
        writeText(path, text);  // edited after the scan
        Run r;
        if (!source) return r;
        Space loaded;
        TerrainMeshes terrain;
        std::vector<Diagnostic> late;
        WindowSequence windows(*source, centres, planner);
        for (size_t k = 0; k < centres.size(); ++k) {
            EXPECT_TRUE(windows.enter(k, loaded, late));
            if (ahead) windows.readAhead(k % 4 == 1 ? k + 2 : k + 1, loaded);
            std::string w;
            for (const auto& [c, cf] : loaded.chunks) {
                w += chunkFileName(c) + " " + std::to_string(cf.contentHash) + ":";
                for (const ChunkObject& o : cf.objects) w += o.skipped ? " skipped" : o.mesh ? " mesh" : " terrain";
                w += "\n";
            }
            r.loaded.push_back(w);
            windows.leave(k, loaded, terrain);
        }
        for (const Diagnostic& d : late) r.late.push_back(d.what());
        return r;
    };
    const Run once = run(false), ahead = run(true);
    ASSERT_EQ(once.loaded.size(), ahead.loaded.size());
    for (size_t k = 0; k < once.loaded.size(); ++k) EXPECT_EQ(once.loaded[k], ahead.loaded[k]) << "window " << k;
    EXPECT_EQ(once.late, ahead.late);
    EXPECT_FALSE(once.late.empty()) << "the edited chunk's malformed resource is a late warning";

    // Part of a load read ahead (every other chunk), the rest read by the load itself.
    writeText(path, original);
    Expected<SpaceSource> a = SpaceSource::scan(space, ""), b = SpaceSource::scan(space, "");
    ASSERT_TRUE(a && b);
    writeText(path, text);
    std::vector<ChunkCoord> half;
    for (size_t k = 0; k < centres.size(); k += 2) half.push_back(centres[k]);
    Space all, some;
    std::vector<Diagnostic> lateAll, lateSome;
    ASSERT_TRUE(a->load(centres, all, lateAll));
    ASSERT_TRUE(b->load(centres, some, lateSome, b->readAhead(half)()));
    ASSERT_EQ(all.chunks.size(), centres.size());
    ASSERT_EQ(some.chunks.size(), centres.size());
    for (ChunkCoord c : centres) EXPECT_EQ(all.chunks.at(c).contentHash, some.chunks.at(c).contentHash);
    ASSERT_EQ(lateAll.size(), lateSome.size());
    for (size_t k = 0; k < lateAll.size(); ++k) EXPECT_EQ(lateAll[k].what(), lateSome[k].what());
}

// A parked mesh is not used once its file was edited after the scan: not when the size
// changes, nor when only the time does (the same size, other bytes).
TEST(SpaceSource, AParkedMeshWhoseFileChangedIsReadAgain) {
    for (const bool sameSize : {false, true}) {
        SCOPED_TRACE(sameSize ? "same size" : "other size");
        const fs::path space = restingSample(freshTestDir(sameSize ? "-same" : "-other"));
        Expected<SpaceSource> source = SpaceSource::scan(space.string(), "");
        ASSERT_TRUE(source);
        ASSERT_GT(source->parkedMeshes(), 0u);
        const fs::path rock = space / "models/rock_a.obj";
        std::string text = readText(rock);
        if (sameSize) {
            // Move the first vertex's first coordinate digit: same length, another mesh.
            const size_t at = text.find("\nv ") + 3;
            ASSERT_NE(at, std::string::npos + 3);
            size_t digit = text.find_first_of("0123456789", at);
            text[digit] = text[digit] == '9' ? '8' : char(text[digit] + 1);
        } else {
            text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        }
        writeText(rock, text);
        expectLoadingRefuses(*source, "rock_a.obj");
    }
}

// The bake that loads chunks as windows need them gives every chunk the verdicts of a bake
// of that chunk alone (which reads its window whole), and holds the columns its windows
// reach, not the grid. Terrain meshes are freed and made again as the window slides: a stage
// cache that kept a freed mesh's entry would hand it to a new mesh at the same address.
TEST(LazyBake, VerdictsAreThoseOfWholeWindowsAndMemoryFollowsTheWindow) {
    const fs::path dir = freshTestDir();
    // 16 chunks wide: under the world's 10-degree sun a window reaches up to 5 chunks along
    // x (core/window_plan.h), and the grid must be wider than what a few windows hold.
    const std::string space = writeStripWorld(dir, 16);
    cli::BakeOptions opt = quickBake(space);
    Expected<cli::BakeResult> whole = cli::runBake(opt);
    ASSERT_TRUE(whole) << whole.error().what();
    ASSERT_EQ(whole->chunks.size(), 80u);
    // 5 chunks deep: in grid order the window of (x, z) holds chunks of columns x - R ..
    // x + R (R: the farthest any window reaches along x), so the bake holds at most the
    // columns x - R .. x + R + 1 at once: what a later window needs stays, the rest goes.
    Expected<SpaceSource> scan = SpaceSource::scan(space, "");
    ASSERT_TRUE(scan);
    const WindowPlanner planner(scan->settings(), scan->chunks(), true);
    int reachX = 0;
    for (const auto& [c, e] : scan->chunks())
        for (ChunkCoord k : planner.plan(c).chunks) reachX = std::max(reachX, std::abs(k.x - c.x));
    EXPECT_GE(reachX, 2) << "the low sun must take windows past the neighbours";
    EXPECT_LE(whole->peakLoadedChunks, size_t(2 * reachX + 2) * 5u);
    EXPECT_LT(whole->peakLoadedChunks, 80u);
    EXPECT_GE(whole->peakLoadedChunks, 9u);
    size_t culled = 0;
    for (size_t k = 0; k < whole->chunks.size(); k += 3) {
        const ChunkVerdicts& cv = whole->chunks[k];
        Expected<cli::ChunkBake> alone = cli::bakeChunk(opt, cv.coord);
        ASSERT_TRUE(alone) << alone.error().what();
        EXPECT_EQ(firstDifference(codes(cv), codes(alone->verdicts)), "") << chunkFileName(cv.coord);
    }
    for (const ChunkVerdicts& cv : whole->chunks)
        for (const ObjectVerdicts& ov : cv.objects)
            for (const Decision& d : ov.decisions) culled += d.verdict == Verdict::Culled && d.stage == std::string_view("geometry");
    EXPECT_GT(culled, 0u) << "the world must exercise the geometry stage's caches";
    // Counted as it went, the same as counted from the kept verdicts.
    EXPECT_EQ(whole->totals.chunks, whole->chunks.size());
    const savings::Tally t = cli::tallyBake(*whole);
    ASSERT_EQ(t.world().size(), whole->totals.savings.world().size());
    for (size_t l = 0; l < t.world().size(); ++l) {
        EXPECT_EQ(t.world()[l].bakeCulls.triangles, whole->totals.savings.world()[l].bakeCulls.triangles);
        EXPECT_EQ(t.world()[l].undecided.casters, whole->totals.savings.world()[l].undecided.casters);
    }
}

// The results file streamed chunk by chunk is, byte for byte, results::writeResults of the
// whole bake; and a --resume bake that skips every chunk streams the same bytes again.
TEST(LazyBake, StreamedResultsAreTheWholeFileByteForByte) {
    const fs::path dir = freshTestDir();
    const std::string space = writeStripWorld(dir);
    cli::BakeOptions opt = quickBake(space);
    opt.write = true;
    opt.outDir = (dir / "out").string();
    opt.resume = true;
    opt.resultsPath = (dir / "r1.json").string();
    Expected<cli::BakeResult> first = cli::runBake(opt);
    ASSERT_TRUE(first) << first.error().what();
    const std::string streamed = readText(dir / "r1.json");
    EXPECT_EQ(streamed, results::writeResults(cli::resultsFile(*first)));
    EXPECT_EQ(first->chunksResumed, 0);

    opt.resultsPath = (dir / "r2.json").string();
    opt.keepVerdicts = false;
    Expected<cli::BakeResult> again = cli::runBake(opt);
    ASSERT_TRUE(again) << again.error().what();
    EXPECT_EQ(again->chunksResumed, 30);
    EXPECT_TRUE(again->chunks.empty() && again->resumedRecords.empty()) << "nothing kept";
    EXPECT_EQ(readText(dir / "r2.json"), streamed);
}

// Each cache keyed by a mesh's address forgets a mesh on request.
TEST(LazyBake, CachesForgetTheMeshesThatGo) {
    Mesh a, b;
    for (Mesh* m : {&a, &b}) {
        m->positions = {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}};
        m->triangles = {{0, 1, 2}};
        m->triangleGroup = {0};
        m->groups.resize(1);
    }
    WindowObject oa, ob;
    oa.mesh = &a, ob.mesh = &b;
    raycast::GroupSampleCache samples(4, 4);
    (void)samples.placed(oa, 0);
    (void)samples.placed(ob, 0);
    ASSERT_EQ(samples.meshGroups(), 2u);
    samples.forget({&b});
    EXPECT_EQ(samples.meshGroups(), 1u);
}

// StagedFile: pieces, a part written again, and nothing left behind when dropped.
TEST(StagedFile, AppendsCutsBackCommitsAndCleansUp) {
    const fs::path dir = freshTestDir();
    const std::string path = (dir / "out.txt").string();
    {
        Expected<StagedFile> f = StagedFile::open(path);
        ASSERT_TRUE(f);
        ASSERT_TRUE(f->append("head\n"));
        const uint64_t mark = f->size();
        ASSERT_TRUE(f->append("a tail that is replaced\n"));
        ASSERT_TRUE(f->truncate(mark));
        ASSERT_TRUE(f->append("tail\n"));
        EXPECT_FALSE(fs::exists(path)) << "nothing replaces the path before commit";
        ASSERT_TRUE(f->sync());
        ASSERT_TRUE(f->commit());
    }
    EXPECT_EQ(readText(path), "head\ntail\n");
    EXPECT_FALSE(fs::exists(tempPathFor(path)));
    {
        Expected<StagedFile> f = StagedFile::open(path);
        ASSERT_TRUE(f);
        ASSERT_TRUE(f->append("never committed\n"));
        EXPECT_TRUE(fs::exists(tempPathFor(path)));
    }
    EXPECT_FALSE(fs::exists(tempPathFor(path))) << "a dropped file removes its temporary";
    EXPECT_EQ(readText(path), "head\ntail\n");
}

// The resume journal: appended per chunk, read back after a kill that tore its last line,
// and compacted to the latest record of each chunk.
TEST(ResumeJournal, KeepsTheLatestRecordPerChunkAndSurvivesATornLine) {
    const fs::path dir = freshTestDir();
    const std::string path = cli::ResumeState::pathIn(dir.string());
    {
        cli::ResumeState s;
        ASSERT_TRUE(s.open(path));
        ASSERT_TRUE(s.record("a.chunk", 1, "A1", "{\"a\": 1}"));
        ASSERT_TRUE(s.record("b.chunk", 2, "B"));
        ASSERT_TRUE(s.record("a.chunk", 3, "A2", "{\"a\": 2}"));
        EXPECT_TRUE(s.upToDate("a.chunk", 3, "A2", true));
        EXPECT_EQ(s.results("a.chunk"), "{\"a\": 2}");
    }
    // A bake killed while appending: half a line at the end.
    std::string text = readText(path);
    writeText(path, text + "{\"chunk\":\"c.chunk\",\"inp");
    cli::ResumeState s;
    ASSERT_TRUE(s.open(path));
    EXPECT_EQ(s.size(), 2u);
    EXPECT_TRUE(s.upToDate("a.chunk", 3, "A2", true)) << "the latest record wins";
    EXPECT_FALSE(s.upToDate("a.chunk", 1, "A1"));
    EXPECT_EQ(s.results("a.chunk"), "{\"a\": 2}");
    EXPECT_TRUE(s.upToDate("b.chunk", 2, "B"));
    EXPECT_FALSE(s.upToDate("b.chunk", 2, "B", true)) << "baked without --results";
    EXPECT_FALSE(s.upToDate("c.chunk", 0, "")) << "a torn record is no record";
    // Rewritten: a header and one line per chunk.
    text = readText(path);
    EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 3);
    EXPECT_EQ(text.find("c.chunk"), std::string::npos);
    // Appending after the rewrite keeps the offsets right.
    ASSERT_TRUE(s.record("d.chunk", 4, "D", "{\"d\": 4}"));
    EXPECT_EQ(s.results("d.chunk"), "{\"d\": 4}");
    EXPECT_EQ(s.results("a.chunk"), "{\"a\": 2}");
    // Another format (the JSON object of older versions): nothing is up to date.
    writeText(path, "{\"format\": \"shadowcull-bake-state\", \"version\": 1, \"chunks\": {}}\n");
    cli::ResumeState old;
    ASSERT_TRUE(old.open(path));
    EXPECT_EQ(old.size(), 0u);
}
