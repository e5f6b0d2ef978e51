#include "cli/resume.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "cli/pipeline.h"
#include "io/chunk_writer.h"
#include "io/file_read.h"
#include "util/hash.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

namespace {

// Bumped whenever a change to the tool may change verdicts for the same input.
constexpr const char* kBakeLogicVersion = "shadowcull-bake-5";

// The settings, lights and the bake options that change verdicts.
void hashSettings(Hasher& h, const SpaceSettings& S, const BakeOptions& opt) {
    h.str(kBakeLogicVersion);
    h.pod(opt.useRaycast).pod(opt.useGeometry).pod(opt.raycast.areaSamples).pod(opt.raycast.maxFeatureSamples);
    h.pod(opt.raycast.maxHitsPerRay).pod(opt.useGpu).pod(opt.gpuBaseline).pod(opt.gpuResolution).pod(opt.gpuTerrain);
    h.pod(opt.gpuCloseUpResolution);
    h.pod(S.chunkSize).pod(S.terrainTolerance);
    // `neighbours` is the window of the original method and of the benchmarks' window-only
    // bake; the analytic bake's windows do not depend on it (core/window_plan.h).
    if (opt.gpuBaseline || opt.neighbourWindows) h.pod(uint8_t(1)).pod(S.neighbours);
    for (const Light& L : S.lights) {
        h.str(L.name).pod(L.type).vec(L.direction).vec(L.position).pod(L.range).pod(L.coneHalfAngleDeg);
        h.pod(L.bias).pod(L.slopeBias).pod(L.filterRadius).pod(L.normalBias);
    }
}

}  // namespace

uint64_t windowInputHash(const SpaceSource& space, ChunkCoord centre, const std::vector<ChunkCoord>& window,
                         const BakeOptions& opt) {
    const SpaceSettings& S = space.settings();
    Hasher h;
    hashSettings(h, S, opt);
    h.pod(centre);
    // Every chunk the window holds (the rectangle and what the shadows reach), by position:
    // a chunk that enters or leaves the window changes the hash as an edit of it does.
    h.pod(uint64_t(window.size()));
    for (ChunkCoord c : window) h.pod(c).pod(space.chunks().at(c).objectsHash);
    return h.value();
}

uint64_t spaceInputHash(const SpaceSource& space, const BakeOptions& opt) {
    Hasher h;
    hashSettings(h, space.settings(), opt);
    h.str(space.settings().spaceDir);  // the results name it
    // Every chunk's objects and its text without the masks (SpaceOutline::contentHash): the
    // masks are the bake's output, which shards baked in place one after another have
    // partly written before the next one reads. The same from a scan and from a plan.
    h.pod(uint64_t(space.outline().chunks)).pod(space.outline().contentHash);
    return h.value();
}

std::string ResumeState::nameFor(int shardIndex, int shardCount) {
    if (shardCount <= 0) return ".shadowcull-bake-state.json";
    return ".shadowcull-bake-state.shard-" + std::to_string(shardIndex) + "-of-" + std::to_string(shardCount) + ".json";
}

std::string ResumeState::pathIn(const std::string& dir, int shardIndex, int shardCount) {
    return (fs::path(dir) / nameFor(shardIndex, shardCount)).string();
}

namespace {

constexpr const char* kStateHeader = "{\"format\":\"shadowcull-bake-state\",\"version\":2}";

// The lines of a journal with their offsets: header first; stops at the first line that
// is not a whole record (a torn append).
struct JournalLine {
    std::string chunk;
    uint64_t input = 0, output = 0;
    bool hasResults = false;
    uint64_t offset = 0, length = 0;
};

bool parseLine(const std::string& line, JournalLine& out) {
    try {
        const nlohmann::json j = nlohmann::json::parse(line);
        out.chunk = j.at("chunk").get<std::string>();
        out.input = std::stoull(j.at("input").get<std::string>(), nullptr, 16);
        out.output = std::stoull(j.at("output").get<std::string>(), nullptr, 16);
        out.hasResults = j.contains("results") && !j["results"].get<std::string>().empty();
        return true;
    } catch (const std::exception&) {
        return false;
    }
}

Status writeAll(int fd, const std::string& bytes, const std::string& path) {
    for (size_t done = 0; done < bytes.size();) {
        const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) return makeError(ErrorKind::Io, path, 0, std::string("cannot append to the bake state: ") + std::strerror(errno));
        done += size_t(n);
    }
    return Status::ok();
}

std::string readAt(const std::string& path, uint64_t offset, uint64_t length) {
    std::ifstream in(path, std::ios::binary);
    std::string s(length, '\0');
    in.seekg(std::streamoff(offset));
    in.read(s.data(), std::streamsize(length));
    return in ? s : std::string();
}

}  // namespace

ResumeState::~ResumeState() {
    if (fd_ >= 0) ::close(fd_);
}

Status ResumeState::open(const std::string& path) {
    entries_.clear();
    path_ = path;
    // Never a FIFO or device to wait on: only a regular file is read.
    std::error_code ec;
    const bool regular = fs::is_regular_file(fs::symlink_status(path, ec));
    std::vector<JournalLine> lines;
    bool clean = regular;  // the file is exactly a header and the latest record per chunk
    if (regular) {
        std::ifstream in(path, std::ios::binary);
        std::string line;
        uint64_t offset = 0;
        bool header = true;
        while (std::getline(in, line)) {
            const uint64_t length = line.size() + 1;
            if (in.eof()) {  // no newline: torn
                clean = false;
                break;
            }
            if (header) {
                header = false;
                if (line != kStateHeader) {
                    clean = false;
                    break;
                }
            } else {
                JournalLine l;
                if (!parseLine(line, l)) {
                    clean = false;
                    break;
                }
                l.offset = offset, l.length = length;
                lines.push_back(std::move(l));
            }
            offset += length;
        }
        if (header) clean = false;  // empty
    }
    std::map<std::string, size_t> latest;
    for (size_t k = 0; k < lines.size(); ++k) latest[lines[k].chunk] = k;
    if (latest.size() != lines.size()) clean = false;
    if (clean) {
        for (const auto& [chunk, k] : latest)
            entries_[chunk] = Entry{lines[k].input, lines[k].output, lines[k].hasResults, lines[k].offset, lines[k].length};
        size_ = fs::file_size(path, ec);
    } else {
        // Rewritten with the latest record per chunk, line by line (never all in memory).
        Expected<StagedFile> out = StagedFile::open(path);
        if (!out) return out.error();
        if (Status s = out->append(std::string(kStateHeader) + "\n"); !s) return s;
        for (const auto& [chunk, k] : latest) {
            const JournalLine& l = lines[k];
            const std::string text = readAt(path, l.offset, l.length);
            if (text.size() != l.length) continue;  // changed under us: bake it again
            entries_[chunk] = Entry{l.input, l.output, l.hasResults, out->size(), l.length};
            if (Status s = out->append(text); !s) return s;
        }
        size_ = out->size();
        if (Status s = out->sync(); !s) return s;
        if (Status s = out->commit(); !s) return s;
    }
    fd_ = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
    if (fd_ < 0) return makeError(ErrorKind::Io, path, 0, std::string("cannot open the bake state: ") + std::strerror(errno));
    return Status::ok();
}

bool ResumeState::upToDate(const std::string& chunk, uint64_t inputHash, const std::string& currentBytes,
                           bool needResults) const {
    auto it = entries_.find(chunk);
    return it != entries_.end() && it->second.input == inputHash &&
           it->second.output == Hasher().str(currentBytes).value() && (!needResults || it->second.hasResults);
}

std::string ResumeState::results(const std::string& chunk) const {
    auto it = entries_.find(chunk);
    if (it == entries_.end() || !it->second.hasResults) return {};
    try {
        return nlohmann::json::parse(readAt(path_, it->second.offset, it->second.length)).at("results").get<std::string>();
    } catch (const std::exception&) {
        return {};  // unreadable now: the chunk is baked again
    }
}

Status ResumeState::record(const std::string& chunk, uint64_t inputHash, const std::string& writtenBytes,
                           const std::string& resultsJson) {
    nlohmann::json j = {{"chunk", chunk}, {"input", hexHash(inputHash)}, {"output", hexHash(Hasher().str(writtenBytes).value())}};
    if (!resultsJson.empty()) j["results"] = resultsJson;
    const std::string line = j.dump() + "\n";
    if (Status s = writeAll(fd_, line, path_); !s) return s;
    if (::fsync(fd_) != 0) return makeError(ErrorKind::Io, path_, 0, std::string("cannot sync the bake state: ") + std::strerror(errno));
    entries_[chunk] = Entry{inputHash, Hasher().str(writtenBytes).value(), !resultsJson.empty(), size_, line.size()};
    size_ += line.size();
    return Status::ok();
}

}  // namespace shadowcull::cli
