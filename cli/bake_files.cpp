#include "cli/bake_files.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "cli/output_guard.h"
#include "cli/report.h"
#include "cli/resume.h"
#include "io/chunk_writer.h"
#include "io/file_read.h"
#include "util/hash.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

namespace {

// The output directory's lock (docs/cli.md): one writing bake per directory at a time, so
// that a second bake can neither remove the first one's staged files nor interleave its
// renames with them. flock() locks die with the process, so a killed bake never leaves a
// stale lock behind; the file itself stays (removing it would race with the next bake).
class OutputLock {
public:
    OutputLock() = default;
    OutputLock(const OutputLock&) = delete;
    OutputLock& operator=(const OutputLock&) = delete;
    ~OutputLock() {
        if (fd_ >= 0) ::close(fd_);  // releases the lock
    }
    // `shared`: a shard's hold on the directory (bake --shard): shards of one bake hold it
    // together, each with its own exclusive lock as well, while a whole bake needs it alone.
    Status acquire(const std::string& dir, const std::string& name = ".shadowcull-bake.lock", bool shared = false) {
        const std::string path = (fs::path(dir) / name).string();
        // Never through a symbolic link: the pid written below would land in its target.
        fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0644);
        if (fd_ < 0 && errno == ELOOP)
            return makeError(ErrorKind::BadInput, path, 0,
                             "the bake lock is a symbolic link; a bake never writes through one (remove it)");
        if (fd_ < 0) return makeError(ErrorKind::Io, path, 0, std::string("cannot create the bake lock: ") + std::strerror(errno));
        if (::flock(fd_, (shared ? LOCK_SH : LOCK_EX) | LOCK_NB) != 0) {
            char pid[32] = {};
            const ssize_t n = ::pread(fd_, pid, sizeof pid - 1, 0);
            std::string holder = n > 0 ? std::string(pid, size_t(n)) : "";
            holder.erase(holder.find_last_not_of(" \n") + 1);
            return makeError(ErrorKind::Busy, path, 0,
                             "another shadowcull bake is writing " + dir +
                                 (holder.empty() ? "" : " (process " + holder + ")") + "; wait for it to finish");
        }
        if (shared) return Status::ok();  // the pid is the exclusive holder's
        const std::string me = std::to_string(::getpid()) + "\n";
        if (::ftruncate(fd_, 0) == 0 && ::pwrite(fd_, me.data(), me.size(), 0) < 0) {
            // The pid is for messages only.
        }
        return Status::ok();
    }

private:
    int fd_ = -1;
};

// A chunk file baked and staged, waiting for its rename.
struct StagedChunk {
    std::string name;    // chunk file name, for messages
    std::string source;  // the chunk file the verdicts were computed from
    uint64_t sourceHash = 0;
    std::string temp, target;
};

const char* const kEditedDuringBake =
    "changed on disk while the bake ran (someone's edit?); not written, so the edit is kept: bake it again";

// Why `source` must not be replaced now: it no longer holds the bytes the bake read (an
// edit made while the bake ran). Empty when it still does.
std::string changedSince(const std::string& source, uint64_t hash) {
    Expected<std::string> now = readRegularFile(source, "chunk file", ErrorKind::Io);
    if (!now) return "cannot be read again (" + now.error().message + ")";
    if (Hasher().str(*now).value() != hash) return kEditedDuringBake;
    return {};
}

// Where a chunk's bytes go: in place (through a symlink, to its target), or a copy under
// --out, by name: a symbolic link there is never followed (writableTargets refuses it).
std::string outputPathFor(const BakeOptions& opt, const std::string& chunkPath) {
    return opt.outDir.empty() ? writeTargetFor(chunkPath) : (fs::path(opt.outDir) / fs::path(chunkPath).filename()).string();
}

// The chunks of `targets` whose output may be written. An output under --out that is a
// symbolic link (a copy of the space made with `cp -as` holds one per chunk, each leading
// back to the space) or one of the bake's inputs stops the bake before anything is
// written; a chunk whose file may not be replaced (read-only, another owner) is left out
// with a warning in `diagnostics`, unless --force-write.
Expected<std::vector<ChunkCoord>> writableTargets(const BakeOptions& opt, const SpaceSource& source,
                                                  const std::vector<ChunkCoord>& targets,
                                                  const std::vector<std::string>& inputs,
                                                  std::vector<Diagnostic>& diagnostics) {
    const bool inPlace = opt.outDir.empty();
    std::vector<ChunkCoord> writable;
    for (ChunkCoord c : targets) {
        const std::string& path = source.chunks().at(c).path;
        const std::string target = outputPathFor(opt, path);
        if (!inPlace) {
            std::error_code ec;
            if (fs::is_symlink(target, ec))
                return makeError(ErrorKind::BadInput, target, 0,
                                 "--out: the output is a symbolic link (to " + fs::read_symlink(target, ec).string() +
                                     "); --out writes copies and never writes through a link (remove it)");
            if (Status s = refuseInputAsOutput(target, inputs, "--out"); !s) return s.error();
        }
        if (std::string why = opt.forceWrite ? "" : replaceRefusal(target); !why.empty()) {
            diagnostics.push_back({path, 0, (inPlace ? "the chunk file is " : "the output " + target + " is ") + why +
                                                "; not baked (--force-write replaces it anyway)"});
            continue;
        }
        // A symlinked chunk is staged beside its target, which may lie outside the
        // output directory: clear a temporary a killed bake left there too.
        if (std::error_code tec; fs::is_regular_file(fs::symlink_status(tempPathFor(target), tec)))
            fs::remove(tempPathFor(target), tec);
        writable.push_back(c);
    }
    return writable;
}

// The masks to write for one chunk, in element order. Skipped objects keep their old <shadow>.
std::vector<ShadowWrite> shadowWrites(const ChunkVerdicts& cv) {
    std::vector<ShadowWrite> out;
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        ShadowWrite w;
        w.write = ov.windowObject >= 0;
        w.terrain = ov.terrain;
        for (int g = 0; g < ov.groupCount; ++g) {
            uint32_t m = cv.groupMask(oi, g);
            w.mask |= m;
            if (!ov.terrain) w.groupMasks.push_back(m);
        }
        out.push_back(std::move(w));
    }
    return out;
}

}  // namespace

std::string writtenNote(const std::vector<std::string>& committed) {
    if (committed.empty()) return "; no chunk file was changed";
    std::string s = "; " + std::to_string(committed.size()) + " chunk file(s) were updated before it, each completely:";
    for (const std::string& c : committed) s += " " + c;
    return s;
}

struct BakeFiles::Impl {
    const BakeOptions& opt;
    BakeResult& result;
    std::vector<std::string>& committed;
    const std::string outDir;
    // Declared first: released last, after the staged files are removed.
    OutputLock lock, shardLock;
    std::vector<StagedChunk> staged;
    ResumeState state;
    const std::string statePath;
    // The results file, one chunk at a time as the chunks are done (staged beside it until
    // the chunk files are committed): the same bytes as results::writeResults of the whole.
    StagedFile resultsOut;
    ResultsBuilder resultsBuilder;
    bool anyResults = false;
    size_t warningsInResults = 0;  // the warnings the results' tail lists
    uint64_t chunksEnd = 0;        // where the results' tail begins

    Impl(const BakeOptions& o, BakeResult& r, std::vector<std::string>& c)
        : opt(o),
          result(r),
          committed(c),
          outDir(o.outDir.empty() ? o.spaceDir : o.outDir),
          statePath(ResumeState::pathIn(outDir, o.shardIndex, o.shardCount)),
          resultsBuilder(r.settings) {}

    // The results' tail after the chunks (it lists the warnings), synced.
    Status writeResultsTail() {
        if (opt.resultsPath.empty()) return Status::ok();
        if (Status s = resultsOut.truncate(chunksEnd); !s) return s;
        if (Status s = resultsOut.append(results::resultsTail(resultsBuilder.tail(result.diagnostics, result.shard), anyResults)); !s)
            return s;
        return resultsOut.sync();
    }

    void discardStaged() {
        for (const StagedChunk& s : staged) fs::remove(s.temp);
    }

    // Renames one staged chunk unless its source changed since it was read (the check and
    // the rename are microseconds apart; the lock keeps other bakes out of that window).
    // `syncDirectory` Later: the caller syncs the directories of every committed target.
    Status commit(const StagedChunk& s, Sync syncDirectory = Sync::Now) {
        if (std::string why = changedSince(s.source, s.sourceHash); !why.empty()) {
            fs::remove(s.temp);
            result.diagnostics.push_back({s.source, 0, why});
            return Status::ok();
        }
        if (Status st = commitStagedFile(s.temp, s.target, syncDirectory); !st) return st;
        committed.push_back(s.name);
        ++result.chunksWritten;
        return Status::ok();
    }

    // The output directory's locks. A shard shares the directory's lock with the other
    // shards, which may be staging files in it: only its own temporaries are cleared (per
    // chunk, writableTargets). A whole bake clears what a killed bake left, under its lock.
    Status lockOutputs(bool sharded) {
        if (opt.write && sharded) {
            if (Status s = lock.acquire(outDir, ".shadowcull-bake.lock", true); !s) return s;
            const std::string name = ".shadowcull-bake.shard-" + std::to_string(opt.shardIndex) + "-of-" + std::to_string(opt.shardCount) + ".lock";
            if (Status s = shardLock.acquire(outDir, name); !s) return s;
        } else if (opt.write) {
            if (Status s = lock.acquire(outDir); !s) return s;
            // Temporaries of a bake that was killed are never chunk files; clear them away
            // (only now: the lock guarantees they are no running bake's).
            if (const int n = removeStaleTempFiles(outDir))
                result.notes.push_back("removed " + std::to_string(n) + " temporary file(s) a killed bake left in " + outDir);
        } else if (!sharded && !staleTempFiles(outDir).empty()) {
            // A dry run writes nothing, but clears what a killed bake left, under the same lock
            // (taken only when there is something to clear; a running bake's files stay).
            if (Status s = lock.acquire(outDir); !s)
                result.notes.push_back("temporary files in " + outDir + " left alone: " + s.error().message);
            else if (const int n = removeStaleTempFiles(outDir))
                result.notes.push_back("removed " + std::to_string(n) + " temporary file(s) a killed bake left in " + outDir);
        }
        return Status::ok();
    }
};

BakeFiles::BakeFiles(const BakeOptions& options, BakeResult& result, std::vector<std::string>& committed)
    : impl_(std::make_unique<Impl>(options, result, committed)) {}

BakeFiles::~BakeFiles() { impl_->discardStaged(); }  // (what --resume committed is recorded already)

bool BakeFiles::resuming() const { return impl_->opt.resume && impl_->opt.write; }

bool BakeFiles::wantResults() const { return !impl_->opt.resultsPath.empty(); }

std::string BakeFiles::targetOf(const std::string& chunkPath) const { return outputPathFor(impl_->opt, chunkPath); }

Status BakeFiles::prepare(const SpaceSource& source, std::vector<ChunkCoord>& targets) {
    const BakeOptions& opt = impl_->opt;
    if (opt.write && !opt.outDir.empty()) {
        // Before the results are probed: they may go into --out too.
        std::error_code ec;
        fs::create_directories(opt.outDir, ec);
        if (ec) return makeError(ErrorKind::Io, opt.outDir, 0, "cannot create output directory: " + ec.message());
    }
    if (Status s = refuseInputAsOutput(opt.resultsPath, impl_->result.inputFiles, "--results"); !s) return s;
    if (!opt.resultsPath.empty()) {
        Expected<std::string> probe = stageFile(opt.resultsPath, "");
        if (!probe) return probe.error();
        fs::remove(*probe);
    }
    if (Status s = impl_->lockOutputs(opt.shardCount > 0); !s) return s;
    if (opt.write) {
        Expected<std::vector<ChunkCoord>> writable =
            writableTargets(opt, source, targets, impl_->result.inputFiles, impl_->result.diagnostics);
        if (!writable) return writable.error();
        targets = std::move(*writable);
    }
    return Status::ok();
}

Status BakeFiles::open() {
    if (resuming())
        if (Status s = impl_->state.open(impl_->statePath); !s) return s;
    if (wantResults()) {
        Expected<StagedFile> f = StagedFile::open(impl_->opt.resultsPath);
        if (!f) return f.error();
        impl_->resultsOut = std::move(*f);
        if (Status s = impl_->resultsOut.append(results::resultsHead()); !s) return s;
    }
    return Status::ok();
}

Expected<bool> BakeFiles::unchanged(const std::string& chunkName, const std::string& target, uint64_t inputHash) {
    Impl& im = *impl_;
    Expected<std::string> current = readRegularFile(target, "chunk file", ErrorKind::Io);
    // With --results, its part of the results as recorded; unreadable (an edited state):
    // bake it again.
    bool skip = current && im.state.upToDate(chunkName, inputHash, *current, wantResults());
    if (skip && wantResults()) {
        Expected<results::ChunkRecord> record = results::parseChunkJson(im.statePath, im.state.results(chunkName));
        skip = bool(record);
        if (record) {
            if (im.opt.keepVerdicts) im.result.resumedRecords.push_back(*record);
            if (Status s = addResults(*record); !s) return s.error();
        }
    }
    return skip;
}

Status BakeFiles::write(const ChunkFile& cf, const std::string& chunkName, const std::string& target, uint64_t inputHash,
                        const ChunkVerdicts& cv, const std::optional<results::ChunkRecord>& record) {
    Impl& im = *impl_;
    // The text to rewrite is the text the objects were read from, or nothing.
    Expected<std::string> text = readRegularFile(cf.path, "chunk file", ErrorKind::Io);
    if (!text) return text.error();
    if (Hasher().str(*text).value() != cf.contentHash) {
        im.result.diagnostics.push_back({cf.path, 0, kEditedDuringBake});
        return Status::ok();
    }
    Expected<std::string> rewritten = rewriteChunkShadows(*text, cf.path, shadowWrites(cv));
    if (!rewritten) return rewritten.error();
    // Complete and synced before any target is replaced: now in long-bake mode (committed
    // at once), else all together before the first rename (BakeFiles::commit).
    Expected<std::string> temp = stageFile(target, *rewritten, !im.opt.forceWrite, resuming() ? Sync::Now : Sync::Later);
    if (!temp) return temp.error();
    StagedChunk sc{chunkName, cf.path, cf.contentHash, *temp, target};
    if (!resuming()) {
        im.staged.push_back(std::move(sc));
        return Status::ok();
    }
    // Long-bake mode: commit now, then record it (a kill between the two only costs baking
    // this chunk again).
    const int before = im.result.chunksWritten;
    if (Status s = im.commit(sc); !s) return s;
    if (im.result.chunksWritten > before)
        if (Status s = im.state.record(chunkName, inputHash, *rewritten, record ? results::chunkJson(*record) : ""); !s)
            return s;
    return Status::ok();
}

Status BakeFiles::addResults(results::ChunkRecord& record) {
    Impl& im = *impl_;
    im.resultsBuilder.add(record);
    const Status s = im.resultsOut.append((im.anyResults ? ",\n" : "\n") + results::chunkJson(record));
    im.anyResults = true;
    return s;
}

Status BakeFiles::finishResults() {
    impl_->warningsInResults = impl_->result.diagnostics.size();
    impl_->chunksEnd = impl_->resultsOut.size();
    return impl_->writeResultsTail();
}

Status BakeFiles::commit() {
    Impl& im = *impl_;
    // Every staged byte durable first (one syncfs per file system, not an fsync per file),
    // then the renames, then each directory synced once: a crash still leaves each chunk
    // file as it was or wholly rewritten.
    std::vector<std::string> temps, targets;
    for (const StagedChunk& sc : im.staged) temps.push_back(sc.temp);
    if (Status s = syncFileSystems(temps); !s) return s;
    for (size_t k = 0; k < im.staged.size(); ++k) {
        if (Status s = im.commit(im.staged[k], Sync::Later); !s) {
            (void)syncDirectories(targets);  // what was renamed stays renamed: make it durable
            im.staged.erase(im.staged.begin(), im.staged.begin() + std::ptrdiff_t(k + 1));
            return s;
        }
        targets.push_back(im.staged[k].target);
    }
    im.staged.clear();
    if (Status s = syncDirectories(targets); !s) return s;
    if (wantResults()) {
        // Refused chunks (edited during the commit) were added to the diagnostics after the
        // results were finished: write the end again so the file lists every warning.
        if (im.result.diagnostics.size() != im.warningsInResults)
            if (Status s = im.writeResultsTail(); !s) return s;
        if (Status s = im.resultsOut.commit(); !s) return s;
    }
    return Status::ok();
}

}  // namespace shadowcull::cli
