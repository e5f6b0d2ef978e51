// Reading a space chunk by chunk, so that a bake's memory follows its window and not the
// world. A bake first scans every chunk file once, in grid order: it parses the
// file and loads each resource the first time an object names it, learns what loadSpace
// would have said (the warnings, in loadSpace's order; the objects that are skipped; the
// files read), and keeps only a summary per chunk and per resource. It then loads a chunk
// again when a window first needs it, and drops it (and the meshes no loaded chunk uses)
// when no window will. loadSpace is the same scan keeping everything.
#pragma once

#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <set>
#include <unordered_map>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/scene.h"
#include "core/window.h"
#include "core/window_plan.h"
#include "io/scene_reader.h"
#include "util/status.h"

namespace shadowcull {

class WindowPlanner;

// Hashes of what a resource gives the stages (bake --resume, shards): the triangles, groups
// and their flags; the heightfield's samples.
uint64_t contentHash(const Mesh& mesh);
uint64_t contentHash(const Heightfield& heightfield);

// What the scan learnt of one resource file, kept after its mesh or heightfield is dropped.
struct ResourceSummary {
    bool usable = false;        // loaded without error (else every object naming it is skipped)
    uint64_t contentHash = 0;   // of the mesh or heightfield (usable only)
    bool hasVertices = false;   // the box below is set
    size_t triangles = 0;       // a mesh's triangles, a heightfield's 2 (n - 1)^2 (usable only)
    // The box of its vertices (metres): a model's in mesh coordinates; a terrain's over its
    // chunk square, chunk-local ([0, S] in x and z, its lowest to highest sample in y).
    glm::dvec3 lo{0.0}, hi{0.0};
    std::vector<std::string> sourceFiles;  // every file read to build it
};


// What a shard needs to know of the whole space beyond the chunks its windows read: a full
// scan learns it, a plan (io/shard_plan.h) carries it to the shards.
struct SpaceOutline {
    size_t chunks = 0;          // chunk files of the space
    // Every chunk's objectsHash and contentWithoutShadowsHash, in grid order: what the
    // shards of one bake must agree on (cli/resume.cpp's spaceInputHash).
    uint64_t contentHash = 0;
    uint64_t listingHash = 0;   // the names of the space directory's *.chunk files, sorted
    uint64_t settingsHash = 0;  // space.xml's bytes and the resource root the bake uses
    SpaceBounds bounds;         // for planning windows (core/window_plan.h)
};

// What a plan gives one shard (io/shard_plan.h): the whole space's outline, warnings and
// inputs, and the summaries of the chunks its windows hold.
struct PlannedSpace {
    std::string spaceDir;  // as the plan was given it (its warnings name files under it)
    SpaceOutline outline;
    std::vector<Diagnostic> diagnostics;      // every warning of reading the space, in loadSpace's order
    std::map<ChunkCoord, ChunkEntry> chunks;  // those the shard's windows hold (contentHash unset)
    // Every input besides space.xml and the chunk files, read from the plan when asked
    // (SpaceSource::readOtherInputs).
    std::function<Expected<std::vector<std::string>>()> otherInputs;
};

// Called by the scan before the first chunk file (0 of `total`) and after each one.
using ScanProgress = std::function<void(size_t scanned, size_t total)>;

class SpaceSource {
public:
    // Reads space.xml, lists the chunk files and scans every one of them (or those of `only`
    // and their neighbours). Errors are loadSpace's: a malformed chunk file stops the scan
    // (the first such file in file-name order, as loadSpace reads them). The files are
    // parsed in parallel, a batch at a time, and resolved in grid order: the same warnings
    // and errors on any number of threads. A stop request (util/stop_request.h) stops it
    // between batches with an Interrupted error.
    static Expected<SpaceSource> scan(const std::string& spaceDir, const std::string& resourceRootOverride,
                                      const std::vector<ChunkCoord>* only = nullptr, const ScanProgress& progress = {});

    // A shard's source from its plan: space.xml is read again and, with the names of the
    // chunk files, checked against the plan (a StalePlan error if they changed); every chunk
    // is checked when it is loaded (load()). Nothing else of the space is read.
    static Expected<SpaceSource> planned(const std::string& spaceDir, const std::string& resourceRootOverride,
                                         PlannedSpace plan);

    const SpaceSettings& settings() const { return settings_; }
    // The whole space's outline (from the scan, or the plan).
    const SpaceOutline& outline() const { return outline_; }
    // Whether this source came from a plan: chunks() then holds only the chunks the shard's
    // windows need, and outline() speaks for the others.
    bool isPlanned() const { return planned_; }
    // Every warning of reading the space, exactly as loadSpace gives them.
    const std::vector<Diagnostic>& diagnostics() const { return diagnostics_; }
    // The chunks scanned, in grid order.
    const std::map<ChunkCoord, ChunkEntry>& chunks() const { return chunks_; }
    // Every file the space was read from, sorted (Space::inputFiles of the whole space).
    // Planned: space.xml, the chunks of the shard's windows and what they use, until
    // readOtherInputs() adds every other chunk file and resource of the space.
    std::vector<std::string> inputFiles() const;
    // Planned: adds the rest of the space's inputs (the listed chunk files, the plan's list
    // of resources) to inputFiles(). A bake asks only when one of its outputs exists, since
    // an output that does not exist cannot be an input.
    Status readOtherInputs();
    // The resource an object names, as the scan found it; null when it names none the scan
    // read (an object skipped before its resource was looked at).
    const ResourceSummary* resource(const ChunkObject& object) const;

    // Puts chunk `c` (one of chunks()) into `space.chunks`, read again, with its objects
    // skipped as the scan skipped them and their meshes attached (loaded again unless a
    // loaded chunk holds them). The chunk keeps the content hash the scan read, so a file
    // edited since is never written by the bake (its text no longer has that hash). A
    // resource that no longer loads, or loads different content, is an Io error: the scan's
    // verdict on it would no longer hold. `lateDiagnostics` gets the warnings about objects
    // an edit since the scan added. From a plan: a chunk whose objects, resources or text
    // (its masks apart) differ from the plan's is a StalePlan error; the bytes of its first
    // load stand for the scan's. A stop request (util/stop_request.h) is an Interrupted
    // error before anything is read.
    Status load(ChunkCoord c, Space& space, std::vector<Diagnostic>& lateDiagnostics);
    // load() of each of `cs` in turn, their files read and parsed in parallel first (a
    // window that slides brings a few chunks at once); the same chunks, errors (the first
    // in `cs` order) and warnings as one load() after another.
    Status load(const std::vector<ChunkCoord>& cs, Space& space, std::vector<Diagnostic>& lateDiagnostics);
    // A chunk file read ahead of its load() (readAhead), and its load with them: the files
    // read ahead are taken as read (an entry left empty, or a chunk not in `ahead`, is read
    // now), then every chunk adopted in `cs` order, as load(cs) does.
    using ReadAhead = std::map<ChunkCoord, Expected<ChunkFile>>;
    Status load(const std::vector<ChunkCoord>& cs, Space& space, std::vector<Diagnostic>& lateDiagnostics, ReadAhead ahead);
    // Reads and parses the files of `cs` now, for a later load(cs, ..., ahead): thread-safe
    // against this source's other calls (it reads only the chunks' paths, taken now; the
    // returned task touches nothing of the source). Warnings are dropped, as reread's.
    std::function<ReadAhead()> readAhead(const std::vector<ChunkCoord>& cs) const;
    // Drops chunk `c` from `space.chunks`, then the meshes and heightfields no loaded chunk
    // uses any more (with their terrain meshes). Returns the meshes that go: whatever is
    // keyed by their address (the stages' caches) must forget them before the caller lets
    // the last reference go, since a mesh loaded later may reuse the address.
    std::vector<std::shared_ptr<const Mesh>> unload(ChunkCoord c, Space& space, TerrainMeshes& terrainMeshes);
    // Resources held for loaded chunks now (tests: memory follows the window).
    size_t liveResources() const { return liveMeshes_.size() + liveTerrains_.size(); }
    // Meshes the scan parsed and kept for the first window that needs them (see parked_).
    size_t parkedMeshes() const { return parked_.size(); }
    // The most mesh memory (bytes, as estimated) the scan keeps parked.
    static constexpr size_t kParkBudget = size_t(64) << 20;

private:
    friend Expected<Space> loadSpace(const std::string&, const std::string&, const std::vector<ChunkCoord>*);
    // The scan; with `keep`, every chunk goes into keep->chunks with its meshes attached.
    static Expected<SpaceSource> read(const std::string& spaceDir, const std::string& resourceRootOverride,
                                      const std::vector<ChunkCoord>* only, Space* keep, const ScanProgress& progress = {});
    // Resolves the objects' resources: skipped flags, reasons and warnings as loadSpace
    // gives them; `attach` also attaches the meshes (loading what is not live).
    Status resolve(ChunkFile& cf, bool attach, std::vector<Diagnostic>& diagnostics);
    std::string keyOf(const ChunkObject& object) const;
    // The summary of a chunk file read and resolved (skipped flags set).
    ChunkEntry entryOf(const ChunkFile& cf, ChunkCoord coord) const;
    // A planned source's check of a chunk it loads against the plan's summary.
    Status checkAgainstPlan(ChunkCoord c, const ChunkFile& cf);
    // Chunk `c`'s file read again (its warnings dropped: the scan or the plan gave them).
    Expected<ChunkFile> reread(ChunkCoord c) const;
    // load() once the file is read: resolved, checked, put into the space.
    Status adopt(ChunkCoord c, Expected<ChunkFile> cf, Space& space, std::vector<Diagnostic>& lateDiagnostics);
    const std::string& fullPath(const std::string& resource) const;  // resource root / resource, normalised

    SpaceSettings settings_;
    SpaceOutline outline_;
    bool planned_ = false;
    std::set<ChunkCoord> loadedOnce_;  // planned: the chunks loaded so far (their contentHash set)
    std::vector<std::string> listed_;  // planned: the names of the space's *.chunk files
    std::function<Expected<std::vector<std::string>>()> otherInputs_;  // planned (PlannedSpace)
    std::map<ChunkCoord, ChunkEntry> chunks_;
    std::vector<Diagnostic> diagnostics_;
    std::set<std::string> inputFiles_;  // space.xml, the chunk files, every resource named
    std::map<std::string, ResourceSummary> resources_;  // by keyOf
    mutable std::unordered_map<std::string, std::string> fullPaths_;  // by resource as written
    // A mesh the scan parsed, kept (within kParkBudget, in scan order) so that the window
    // that first needs it does not parse its files again (world D: 13 MB of OBJ, a tenth of
    // the bake). Taken only while every file it was read from still has the size and
    // modification time it had, and had them before the parse began (by 2 s: a file written
    // during or after the parse gets a later time), else parsed again and compared by hash,
    // as for a mesh that was not parked.
    struct FileStamp {
        std::string path;
        uintmax_t size = 0;
        std::filesystem::file_time_type time;
    };
    struct Parked {
        std::shared_ptr<const Mesh> mesh;
        std::vector<FileStamp> stamps;
        size_t bytes = 0;
    };
    // Parks `mesh` (just parsed from its files, the parse begun at `parseStart`) when the
    // budget allows and its files' times are older than the parse.
    void park(const std::string& key, std::shared_ptr<const Mesh> mesh, std::filesystem::file_time_type parseStart);
    // The parked mesh for `key` if its files are unchanged (removed from the park either way).
    std::shared_ptr<const Mesh> unpark(const std::string& key);
    std::map<std::string, Parked> parked_;
    size_t parkedBytes_ = 0;
    // Meshes and heightfields attached to loaded chunks, by keyOf.
    std::map<std::string, std::shared_ptr<const Mesh>> liveMeshes_;
    std::map<std::string, std::shared_ptr<const Heightfield>> liveTerrains_;
};

// The windows of a bake, one after the other: before window k, the chunks it holds are
// loaded (those not loaded yet); after it, those no later window holds are dropped. In grid
// order a bake holds about two columns of the grid at a time, whatever the grid's size.
class WindowSequence {
public:
    // `centres`: the chunks baked, in the order they will be; each window holds the chunks
    // `planner` plans for its centre (core/window_plan.h: what the shadows reach, or the
    // `neighbours` rectangle). The planner must outlive the sequence.
    WindowSequence(SpaceSource& source, std::vector<ChunkCoord> centres, const WindowPlanner& planner);
    // The chunks window k holds, in grid order (what buildWindow is given).
    std::vector<ChunkCoord> window(size_t k) const;
    // Loads what window k holds into `space` (SpaceSource::load).
    Status enter(size_t k, Space& space, std::vector<Diagnostic>& lateDiagnostics);
    // Drops what no window after k holds (SpaceSource::unload); returns the meshes that go,
    // for the caches keyed by their address to forget first.
    std::vector<std::shared_ptr<const Mesh>> leave(size_t k, Space& space, TerrainMeshes& terrainMeshes);
    // The most chunks `space` held at once so far.
    size_t peakLoaded() const { return peak_; }
    // Starts reading, on a thread of its own, the chunk files window k will load that
    // `space` does not hold (call after entering window k - 1: its bake hides the reads);
    // enter(k) takes them. Only the files are read there (no resolving, no space change).
    void readAhead(size_t k, const Space& space);
    // Waits for a read-ahead in flight (before the source or the space goes).
    ~WindowSequence();

private:
    std::vector<ChunkCoord> missing(size_t k, const Space& space) const;
    SpaceSource& source_;
    const WindowPlanner& planner_;
    std::vector<ChunkCoord> centres_;
    std::map<ChunkCoord, size_t> lastUse_;  // the last window holding each chunk
    size_t peak_ = 0;
    size_t aheadFor_ = 0;  // the window the read-ahead is for
    std::future<SpaceSource::ReadAhead> ahead_;
};

}  // namespace shadowcull
