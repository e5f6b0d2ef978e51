// The space scan and lazy chunk loading (io/space_source.h), and loadSpace on top of them.

#include "io/space_source.h"

#include <dirent.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <set>
#include <unordered_map>

#include <glm/common.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include "core/limits.h"
#include "core/window_plan.h"
#include "io/file_read.h"
#include "io/scene_reader.h"
#include "util/format.h"
#include "util/hash.h"
#include "util/stop_request.h"

namespace fs = std::filesystem;

namespace shadowcull {

uint64_t contentHash(const Mesh& m) {
    Hasher h;
    auto bits = [](double v) {
        uint64_t w;
        std::memcpy(&w, &v, sizeof w);
        return w;
    };
    h.pod(uint64_t(m.positions.size()));
    for (const glm::dvec3& p : m.positions) h.word(bits(p.x)).word(bits(p.y)).word(bits(p.z));
    h.pod(uint64_t(m.triangles.size()));
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        const auto& tri = m.triangles[t];
        h.word(uint64_t(tri[0]) | uint64_t(tri[1]) << 32).word(uint64_t(tri[2]) | uint64_t(m.triangleGroup[t]) << 32);
    }
    for (const PrimitiveGroup& g : m.groups) h.pod(g.alphaTested).pod(g.doubleSided);
    return h.value();
}

uint64_t contentHash(const Heightfield& hf) {
    Hasher h;
    h.pod(hf.n).pod(hf.size);
    h.bytes(hf.heights.data(), hf.heights.size() * sizeof(double));
    return h.value();
}

namespace {

Error bad(const std::string& file, int line, const std::string& msg) { return makeError(ErrorKind::BadInput, file, line, msg); }

const char* const kObjectSkipped = "; object skipped (its <shadow> is left as it was)";

// Why a placed mesh lies outside what the stages can represent (core/limits.h), or nothing.
// The bounds of the mesh's box under the transform bound every placed vertex.
std::optional<std::string> placedBeyondLimits(const ResourceSummary& mesh, const RowTransform& t) {
    if (!mesh.hasVertices) return std::nullopt;
    double reach = 0;
    for (int k = 0; k < 8; ++k) {
        const glm::dvec3 corner((k & 1) ? mesh.hi.x : mesh.lo.x, (k & 2) ? mesh.hi.y : mesh.lo.y, (k & 4) ? mesh.hi.z : mesh.lo.z);
        const glm::dvec3 q = t.apply(corner);
        reach = std::max({reach, std::abs(q.x), std::abs(q.y), std::abs(q.z)});
    }
    if (reach <= limits::kMaxLocalCoordinate) return std::nullopt;
    return "placed, the mesh reaches " + formatNumber(reach) + " m from its chunk origin, beyond the accepted " +
           formatNumber(limits::kMaxLocalCoordinate) + " m (docs/format.md, accepted ranges)";
}

// The world-space box of an object's vertices from its resource's box: placed by its
// transform and its chunk's origin, widened against rounding (placedBounds).
Aabb wsObjectBounds(const ResourceSummary& rs, const ChunkObject& o, ChunkCoord c, double chunkSize) {
    RowTransform wsFromMesh = o.kind == ChunkObject::Kind::Model ? o.transform : RowTransform{};
    wsFromMesh.rows[3] += glm::dvec3(double(c.x) * chunkSize, 0.0, double(c.z) * chunkSize);
    return placedBounds(Aabb{rs.lo, rs.hi}, wsFromMesh);
}

ResourceSummary summarize(const Mesh& m) {
    ResourceSummary s;
    s.usable = true;
    s.contentHash = contentHash(m);
    s.lo = glm::dvec3(std::numeric_limits<double>::max());
    s.hi = glm::dvec3(-std::numeric_limits<double>::max());
    for (const glm::dvec3& p : m.positions) {
        s.lo = glm::min(s.lo, p);
        s.hi = glm::max(s.hi, p);
    }
    s.hasVertices = !m.positions.empty();
    s.triangles = m.triangles.size();
    s.sourceFiles = m.sourceFiles;
    return s;
}

ResourceSummary summarize(const Heightfield& hf) {
    ResourceSummary s;
    s.usable = true;
    s.contentHash = contentHash(hf);
    if (!hf.heights.empty()) {
        const auto [lo, hi] = std::minmax_element(hf.heights.begin(), hf.heights.end());
        s.lo = glm::dvec3(0.0, *lo, 0.0);
        s.hi = glm::dvec3(hf.size, *hi, hf.size);
        s.hasVertices = true;
    }
    s.triangles = hf.n > 1 ? 2 * size_t(hf.n - 1) * size_t(hf.n - 1) : 0;
    s.sourceFiles = hf.sourceFiles;
    return s;
}

// The names of the space directory's *.chunk files, sorted (the order loadSpace reads
// them). Plain readdir: a shard given a plan lists a world's names at every start, and
// building a filesystem::path per entry was most of that.
Expected<std::vector<std::string>> chunkFileNamesIn(const std::string& spaceDir) {
    std::unique_ptr<DIR, int (*)(DIR*)> dir(::opendir(spaceDir.c_str()), ::closedir);
    if (!dir) return makeError(ErrorKind::BadInput, spaceDir, 0, std::string("cannot list the space directory: ") + std::strerror(errno));
    std::vector<std::string> names;
    static constexpr std::string_view kExtension = ".chunk";
    errno = 0;
    while (const dirent* entry = ::readdir(dir.get())) {
        const std::string_view name = entry->d_name;
        // As filesystem::path::extension(): a name that is only ".chunk" has none.
        if (name.size() > kExtension.size() && name.substr(name.size() - kExtension.size()) == kExtension)
            names.emplace_back(name);
    }
    if (errno != 0) return makeError(ErrorKind::BadInput, spaceDir, 0, std::string("cannot list the space directory: ") + std::strerror(errno));
    std::sort(names.begin(), names.end());
    return names;
}

uint64_t listingHashOf(const std::vector<std::string>& names) {
    Hasher h;
    h.pod(uint64_t(names.size()));
    for (const std::string& name : names) h.str(name);
    return h.value();
}

// Each chunk file with its position in file-name order (the order warnings and errors of
// reading the files follow, as loadSpace has always read them), from the directory's sorted
// *.chunk names; a name that is no chunk's is a warning, two names of one chunk an error.
using NamedChunkFiles = std::map<ChunkCoord, std::pair<fs::path, size_t>>;
Expected<NamedChunkFiles> namedChunkFiles(const std::string& spaceDir, const std::vector<std::string>& names,
                                          std::vector<Diagnostic>& nameWarnings) {
    if (names.empty())
        return bad(spaceDir, 0, "the space has a space.xml but no chunk files (XXXXZZZZo.chunk beside it): nothing to bake");
    NamedChunkFiles named;
    for (size_t k = 0; k < names.size(); ++k) {
        const fs::path p = fs::path(spaceDir) / names[k];
        std::optional<ChunkCoord> c = parseChunkName(names[k]);
        if (!c) {
            nameWarnings.push_back({p.string(), 0, "not a chunk name (XXXXZZZZo.chunk, 16-bit hex); file ignored"});
            continue;
        }
        // Hex digits in either case name the same chunk: two such files are two versions of
        // one chunk, and baking either would silently drop the other.
        if (auto [it, added] = named.emplace(*c, std::make_pair(p, k)); !added)
            return bad(p.string(), 0, "names the same chunk as " + it->second.first.filename().string() + " (grid " +
                                          std::to_string(c->x) + ", " + std::to_string(c->z) +
                                          "); keep one of the two files");
    }
    if (named.empty()) {
        std::string some;
        for (size_t k = 0; k < names.size() && k < 3; ++k) some += (k ? ", " : "") + names[k];
        return bad(spaceDir, 0, "the space has no chunk files: " + std::to_string(names.size()) + " file(s) end in .chunk (" +
                                    some + (names.size() > 3 ? ", ..." : "") +
                                    "), but none is named XXXXZZZZo.chunk (16-bit hex grid x and z)");
    }
    return named;
}

// space.xml's bytes and the resource root the bake resolved from it (and --res).
Expected<uint64_t> settingsHashOf(const SpaceSettings& S) {
    Expected<std::string> xml = readRegularFile((fs::path(S.spaceDir) / "space.xml").string(), "space.xml", ErrorKind::BadInput);
    if (!xml) return xml.error();
    return Hasher().str(*xml).str(S.resourceRoot).value();
}

uint64_t contentHashOf(const std::map<ChunkCoord, ChunkEntry>& chunks) {
    Hasher h;
    h.pod(uint64_t(chunks.size()));
    for (const auto& [coord, e] : chunks) h.pod(coord).pod(e.objectsHash).pod(e.contentWithoutShadowsHash);
    return h.value();
}

}  // namespace

const std::string& SpaceSource::fullPath(const std::string& resource) const {
    // Memoised: a world names a few resources hundreds of thousands of times, and path
    // arithmetic was a tenth of the scan.
    auto it = fullPaths_.find(resource);
    if (it == fullPaths_.end())
        it = fullPaths_.emplace(resource, (fs::path(settings_.resourceRoot) / resource).lexically_normal().string()).first;
    return it->second;
}

std::string SpaceSource::keyOf(const ChunkObject& o) const {
    // Models and terrains are loaded differently: the same path is two resources.
    return (o.kind == ChunkObject::Kind::Model ? "m:" : "t:") + fullPath(o.resource);
}

const ResourceSummary* SpaceSource::resource(const ChunkObject& o) const {
    if (o.resource.empty()) return nullptr;
    auto it = resources_.find(keyOf(o));
    return it == resources_.end() ? nullptr : &it->second;
}

Status SpaceSource::resolve(ChunkFile& cf, bool attach, std::vector<Diagnostic>& diagnostics) {
    // The resources this chunk uses first, loaded in parallel (a dense world's few unique
    // meshes, parsed one after the other, were most of its scan), then judged below in
    // object order, as before: the diagnostics and what is kept do not depend on threads.
    struct FirstUse {
        std::string key;
        fs::file_time_type parseStart;
        std::shared_ptr<const Mesh> mesh;
        std::shared_ptr<const Heightfield> terrain;
        std::optional<Error> error;
        std::vector<Diagnostic> warnings;  // what the resource's reader ignored
        ResourceSummary summary;
    };
    std::vector<FirstUse> firstUses;
    std::unordered_map<std::string, size_t> firstUseOf;
    for (const ChunkObject& o : cf.objects) {
        if (o.skipped) continue;
        std::string key = keyOf(o);
        if (resources_.count(key) || firstUseOf.count(key)) continue;
        firstUseOf.emplace(key, firstUses.size());
        firstUses.push_back({std::move(key), {}, nullptr, nullptr, std::nullopt, {}, {}});
    }
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, firstUses.size(), 1),
        [&](const tbb::blocked_range<size_t>& range) {
            for (size_t k = range.begin(); k != range.end(); ++k) {
                FirstUse& u = firstUses[k];
                const std::string full = u.key.substr(2);
                if (u.key[0] == 'm') {
                    u.parseStart = fs::file_time_type::clock::now();
                    Expected<Mesh> m = loadModelResource(full, &u.warnings);
                    if (!m) u.error = m.error();
                    else u.mesh = std::make_shared<const Mesh>(std::move(*m)), u.summary = summarize(*u.mesh);
                } else {
                    Expected<Heightfield> t = loadTerrainResource(full, settings_.chunkSize, &u.warnings);
                    if (!t) u.error = t.error();
                    else u.terrain = std::make_shared<const Heightfield>(std::move(*t)), u.summary = summarize(*u.terrain);
                }
            }
        },
        tbb::simple_partitioner());
    for (ChunkObject& o : cf.objects) {
        if (o.skipped) continue;
        const std::string key = keyOf(o);
        const std::string full = key.substr(2);
        const bool model = o.kind == ChunkObject::Kind::Model;
        auto found = resources_.find(key);
        std::shared_ptr<const Mesh> mesh;
        std::shared_ptr<const Heightfield> terrain;
        if (found == resources_.end()) {
            // First use: load it, and say once what is wrong with it (the objects are named
            // one by one below).
            FirstUse& u = firstUses[firstUseOf.at(key)];
            diagnostics.insert(diagnostics.end(), u.warnings.begin(), u.warnings.end());
            if (u.error) diagnostics.push_back({u.error->file, u.error->line, u.error->message + "; every object using it is skipped"});
            mesh = std::move(u.mesh);
            terrain = std::move(u.terrain);
            if (mesh && !attach) park(key, mesh, u.parseStart);
            found = resources_.emplace(key, std::move(u.summary)).first;
            if (mesh) liveMeshes_.emplace(key, mesh);
            if (terrain) liveTerrains_.emplace(key, terrain);
        }
        const ResourceSummary& s = found->second;
        if (!s.usable) {
            o.skipped = true;
            o.skipReason = "resource " + o.resource + " could not be loaded";
            diagnostics.push_back({cf.path, o.line, o.skipReason + kObjectSkipped});
            continue;
        }
        if (model)
            if (std::optional<std::string> far = placedBeyondLimits(s, o.transform)) {
                o.skipped = true;
                o.skipReason = *far;
                diagnostics.push_back({cf.path, o.line, *far + kObjectSkipped});
                continue;
            }
        if (!attach) continue;
        // Attach what a loaded chunk holds, or load it again: it must be what the scan read.
        if (model) {
            auto live = liveMeshes_.find(key);
            if (live == liveMeshes_.end())
                if (std::shared_ptr<const Mesh> parked = unpark(key)) live = liveMeshes_.emplace(key, std::move(parked)).first;
            if (live == liveMeshes_.end()) {
                Expected<Mesh> m = loadModelResource(full);
                if (!m || contentHash(*m) != s.contentHash)
                    return makeError(ErrorKind::Io, full, 0, "changed on disk while the bake ran (it was read at the start); bake again");
                live = liveMeshes_.emplace(key, std::make_shared<const Mesh>(std::move(*m))).first;
            }
            o.mesh = live->second;
        } else {
            auto live = liveTerrains_.find(key);
            if (live == liveTerrains_.end()) {
                Expected<Heightfield> t = loadTerrainResource(full, settings_.chunkSize);
                if (!t || contentHash(*t) != s.contentHash)
                    return makeError(ErrorKind::Io, full, 0, "changed on disk while the bake ran (it was read at the start); bake again");
                live = liveTerrains_.emplace(key, std::make_shared<const Heightfield>(std::move(*t))).first;
            }
            o.heightfield = live->second;
        }
    }
    return Status::ok();
}

void SpaceSource::park(const std::string& key, std::shared_ptr<const Mesh> mesh, fs::file_time_type parseStart) {
    const size_t bytes = mesh->positions.size() * sizeof(glm::dvec3) +
                         mesh->triangles.size() * (sizeof(mesh->triangles[0]) + sizeof(mesh->triangleGroup[0]));
    if (parkedBytes_ + bytes > kParkBudget) return;
    Parked p{std::move(mesh), {}, bytes};
    for (const std::string& file : p.mesh->sourceFiles) {
        std::error_code ec;
        FileStamp st{file, fs::file_size(file, ec), {}};
        if (!ec) st.time = fs::last_write_time(file, ec);
        // A file written around the parse may hold other bytes than were read.
        if (ec || st.time > parseStart - std::chrono::seconds(2)) return;
        p.stamps.push_back(std::move(st));
    }
    parkedBytes_ += bytes;
    parked_.emplace(key, std::move(p));
}

std::shared_ptr<const Mesh> SpaceSource::unpark(const std::string& key) {
    auto it = parked_.find(key);
    if (it == parked_.end()) return nullptr;
    Parked p = std::move(it->second);
    parked_.erase(it);
    parkedBytes_ -= p.bytes;
    for (const FileStamp& st : p.stamps) {
        std::error_code ec;
        const uintmax_t size = fs::file_size(st.path, ec);
        if (ec || size != st.size) return nullptr;
        const fs::file_time_type time = fs::last_write_time(st.path, ec);
        if (ec || time != st.time) return nullptr;
    }
    return std::move(p.mesh);
}

Expected<SpaceSource> SpaceSource::read(const std::string& spaceDir, const std::string& resourceRootOverride,
                                        const std::vector<ChunkCoord>* only, Space* keep, const ScanProgress& progress) {
    SpaceSource src;
    Expected<SpaceSettings> st = readSpaceSettings(spaceDir, resourceRootOverride);
    if (!st) return st.error();
    src.settings_ = std::move(*st);
    const SpaceSettings& S = src.settings_;

    // Which chunks to read: all, or the named ones and their neighbours.
    std::set<ChunkCoord> wanted;
    if (only) {
        for (ChunkCoord c : *only)
            for (int dx = -S.neighbours.left; dx <= S.neighbours.right; ++dx)
                for (int dz = -S.neighbours.bottom; dz <= S.neighbours.top; ++dz) wanted.insert({c.x + dx, c.z + dz});
    }
    Expected<std::vector<std::string>> listed = chunkFileNamesIn(spaceDir);
    if (!listed) return listed.error();
    std::vector<Diagnostic> nameWarnings;
    Expected<NamedChunkFiles> namedFiles = namedChunkFiles(spaceDir, *listed, nameWarnings);
    if (!namedFiles) return namedFiles.error();
    const NamedChunkFiles& named = *namedFiles;

    // In grid order: read each chunk, resolve its resources, show it, drop it (or keep it).
    // The warnings of reading a file are kept by file order, those of its resources come in
    // grid order: loadSpace's order.
    std::map<size_t, std::vector<Diagnostic>> readWarnings;  // by file order
    std::vector<Diagnostic> resourceWarnings;
    std::set<std::string> namedResources;                     // every resource path an object names
    std::vector<std::pair<ChunkCoord, const std::pair<fs::path, size_t>*>> toRead;  // grid order
    for (const auto& [coord, file] : named)
        if (!only || wanted.count(coord)) toRead.emplace_back(coord, &file);
    // loadSpace stops at the first malformed file in file order: one of those after chunk
    // `k` in grid order (not read yet, one by one) may come before it.
    auto firstMalformed = [&](size_t k, Error first) {
        size_t firstOrder = toRead[k].second->second;
        for (size_t j = k + 1; j < toRead.size(); ++j) {
            const auto& [c2, f2] = toRead[j];
            if (f2->second >= firstOrder) continue;
            std::vector<Diagnostic> ignored;
            if (Expected<ChunkFile> e = readChunkFile(f2->first.string(), c2, ignored); !e) first = e.error(), firstOrder = f2->second;
        }
        return first;
    };
    if (progress) progress(0, toRead.size());
    // In batches: a batch's files parsed in parallel (a large world's scan is mostly XML: a
    // plan of 10,000 chunk files took 36 s on one thread), then resolved one by one in grid
    // order as before, so the warnings, skips and errors do not depend on threads.
    constexpr size_t kBatch = 64;
    for (size_t b0 = 0; b0 < toRead.size(); b0 += kBatch) {
        // A world's scan takes minutes: a signal stops it between batches.
        if (Status s = stopStatus(); !s) return s.error();
        const size_t b1 = std::min(toRead.size(), b0 + kBatch);
        std::vector<std::optional<Expected<ChunkFile>>> parsed(b1 - b0);
        std::vector<std::vector<Diagnostic>> warnings(b1 - b0);
        tbb::parallel_for(tbb::blocked_range<size_t>(b0, b1, 1), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t k = range.begin(); k != range.end(); ++k)
                parsed[k - b0].emplace(readChunkFile(toRead[k].second->first.string(), toRead[k].first, warnings[k - b0]));
        });
        for (size_t k = b0; k < b1; ++k) {
            const ChunkCoord coord = toRead[k].first;
            readWarnings[toRead[k].second->second] = std::move(warnings[k - b0]);
            Expected<ChunkFile>& cf = *parsed[k - b0];
            if (!cf) return firstMalformed(k, cf.error());
            for (const ChunkObject& o : cf->objects)
                if (!o.resource.empty()) namedResources.insert(src.fullPath(o.resource));
            if (Status s = src.resolve(*cf, keep != nullptr, resourceWarnings); !s) return s.error();
            src.chunks_.emplace(coord, src.entryOf(*cf, coord));
            if (keep) {
                keep->chunks.emplace(coord, std::move(*cf));
            } else {
                // Only this chunk's objects held them: the meshes go (a later use finds their
                // summary; the bake loads them again when a window needs them).
                src.liveMeshes_.clear();
                src.liveTerrains_.clear();
            }
            parsed[k - b0].reset();
            if (progress) progress(k + 1, toRead.size());
        }
    }
    if (keep) {
        // The objects hold their meshes; the source lets them go with the objects.
        src.liveMeshes_.clear();
        src.liveTerrains_.clear();
    }
    src.diagnostics_ = std::move(nameWarnings);
    for (auto& [order, warnings] : readWarnings)
        src.diagnostics_.insert(src.diagnostics_.end(), warnings.begin(), warnings.end());
    src.diagnostics_.insert(src.diagnostics_.end(), resourceWarnings.begin(), resourceWarnings.end());
    // The files: space.xml, the chunk files, every resource named and the files behind
    // those that were used (Space::inputFiles).
    std::set<std::string> inputs{(fs::path(S.spaceDir) / "space.xml").string()};
    for (const auto& [coord, e] : src.chunks_) inputs.insert(e.path);
    inputs.insert(namedResources.begin(), namedResources.end());
    src.inputFiles_ = std::move(inputs);
    Expected<uint64_t> settingsHash = settingsHashOf(S);
    if (!settingsHash) return settingsHash.error();
    src.outline_ = {src.chunks_.size(), contentHashOf(src.chunks_), listingHashOf(*listed), *settingsHash,
                    spaceBoundsOf(S, src.chunks_)};
    return src;
}

ChunkEntry SpaceSource::entryOf(const ChunkFile& cf, ChunkCoord coord) const {
    ChunkEntry entry{cf.path, cf.contentHash, cf.contentWithoutShadowsHash, 0, 0, {}};
    Hasher h;
    h.pod(coord);
    for (const ChunkObject& o : cf.objects) {
        entry.usableObjects += o.skipped ? 0 : 1;
        h.pod(o.kind).pod(o.elementIndex).str(o.resource).str(o.uuid).pod(o.castsShadow).pod(o.skipped);
        for (const glm::dvec3& r : o.transform.rows) h.vec(r);
        if (o.skipped) continue;
        const ResourceSummary& rs = *resource(o);
        h.pod(rs.contentHash);
        entry.triangles += rs.triangles;
        if (rs.hasVertices) entry.wsBounds.extend(wsObjectBounds(rs, o, coord, settings_.chunkSize));
    }
    entry.objectsHash = h.value();
    return entry;
}

Expected<SpaceSource> SpaceSource::planned(const std::string& spaceDir, const std::string& resourceRootOverride,
                                           PlannedSpace plan) {
    // What the shard reads of the whole space: space.xml and the directory's names. Both
    // must be as the plan saw them; the chunks are checked as they are loaded.
    auto stale = [&](const std::string& file, const std::string& what) {
        return makeError(ErrorKind::StalePlan, file, 0,
                         what + " since the plan was made: plan again (shadowcull plan), then bake the shards");
    };
    std::error_code ec;
    if (!fs::equivalent(plan.spaceDir, spaceDir, ec))
        return makeError(ErrorKind::BadInput, spaceDir, 0, "the plan is of another space (" + plan.spaceDir + ")");
    SpaceSource src;
    Expected<SpaceSettings> st = readSpaceSettings(spaceDir, resourceRootOverride);
    if (!st) return st.error();
    src.settings_ = std::move(*st);
    Expected<uint64_t> settingsHash = settingsHashOf(src.settings_);
    if (!settingsHash) return settingsHash.error();
    const std::string spaceXml = (fs::path(src.settings_.spaceDir) / "space.xml").string();
    if (*settingsHash != plan.outline.settingsHash)
        return stale(spaceXml, "space.xml, or the resource root (--res), changed");
    Expected<std::vector<std::string>> files = chunkFileNamesIn(spaceDir);
    if (!files) return files.error();
    if (listingHashOf(*files) != plan.outline.listingHash) return stale(spaceDir, "chunk files were added, removed or renamed");
    src.planned_ = true;
    src.outline_ = plan.outline;
    src.diagnostics_ = std::move(plan.diagnostics);
    src.chunks_ = std::move(plan.chunks);
    src.listed_ = std::move(*files);
    src.otherInputs_ = std::move(plan.otherInputs);
    src.inputFiles_.insert(spaceXml);
    for (auto& [coord, e] : src.chunks_) {
        // The file the shard's own listing names (the space as this shard was given it).
        e.path = (fs::path(spaceDir) / fs::path(e.path).filename()).string();
        src.inputFiles_.insert(e.path);
    }
    return src;
}

Status SpaceSource::readOtherInputs() {
    if (!planned_ || !otherInputs_) return Status::ok();
    Expected<std::vector<std::string>> others = otherInputs_();
    if (!others) return others.error();
    inputFiles_.insert(others->begin(), others->end());
    for (const std::string& name : listed_)
        if (parseChunkName(name)) inputFiles_.insert((fs::path(settings_.spaceDir) / name).string());
    otherInputs_ = nullptr;
    return Status::ok();
}

Status SpaceSource::checkAgainstPlan(ChunkCoord c, const ChunkFile& cf) {
    const ChunkEntry& fromPlan = chunks_.at(c);
    const ChunkEntry now = entryOf(cf, c);
    // The box too: the windows were planned on the plan's boxes, and a box that is not the
    // chunk's (a plan edited by hand) could leave a receiver out of them.
    const bool sameBox = now.wsBounds.min == fromPlan.wsBounds.min && now.wsBounds.max == fromPlan.wsBounds.max;
    if (now.objectsHash != fromPlan.objectsHash || now.contentWithoutShadowsHash != fromPlan.contentWithoutShadowsHash ||
        now.usableObjects != fromPlan.usableObjects || !sameBox)
        return makeError(ErrorKind::StalePlan, cf.path, 0,
                         "changed since the plan was made (its objects, their resources, or its text apart from the "
                         "masks), or the plan's summary of it is not its own: plan again (shadowcull plan), then "
                         "bake the shards");
    return Status::ok();
}

Expected<SpaceSource> SpaceSource::scan(const std::string& spaceDir, const std::string& resourceRootOverride,
                                        const std::vector<ChunkCoord>* only, const ScanProgress& progress) {
    return read(spaceDir, resourceRootOverride, only, nullptr, progress);
}

std::vector<std::string> SpaceSource::inputFiles() const {
    std::set<std::string> files = inputFiles_;
    for (const auto& [key, s] : resources_)
        if (s.usable) files.insert(s.sourceFiles.begin(), s.sourceFiles.end());
    return {files.begin(), files.end()};
}

Expected<ChunkFile> SpaceSource::reread(ChunkCoord c) const {
    std::vector<Diagnostic> ignored;  // the scan (or the plan) gave these
    return readChunkFile(chunks_.at(c).path, c, ignored);
}

Status SpaceSource::load(ChunkCoord c, Space& space, std::vector<Diagnostic>& lateDiagnostics) {
    // A window of large chunks takes seconds to load: a signal stops it between them.
    if (Status s = stopStatus(); !s) return s;
    return adopt(c, reread(c), space, lateDiagnostics);
}

Status SpaceSource::load(const std::vector<ChunkCoord>& cs, Space& space, std::vector<Diagnostic>& lateDiagnostics) {
    return load(cs, space, lateDiagnostics, ReadAhead{});
}

Status SpaceSource::load(const std::vector<ChunkCoord>& cs, Space& space, std::vector<Diagnostic>& lateDiagnostics,
                         ReadAhead ahead) {
    if (cs.size() < 2 && ahead.empty()) return cs.empty() ? Status::ok() : load(cs[0], space, lateDiagnostics);
    if (Status s = stopStatus(); !s) return s;
    std::vector<ChunkCoord> rest;  // not read ahead: read now, in parallel
    for (ChunkCoord c : cs)
        if (!ahead.count(c)) rest.push_back(c);
    std::vector<std::optional<Expected<ChunkFile>>> read(rest.size());
    tbb::parallel_for(size_t(0), rest.size(), [&](size_t k) {
        if (!stopRequested()) read[k].emplace(reread(rest[k]));  // else left unread: read below
    });
    for (size_t k = 0; k < rest.size(); ++k)
        if (read[k]) ahead.emplace(rest[k], std::move(*read[k]));
    for (ChunkCoord c : cs) {
        if (Status s = stopStatus(); !s) return s;
        auto it = ahead.find(c);
        if (it == ahead.end()) it = ahead.emplace(c, reread(c)).first;  // left unread by a stop request withdrawn since
        if (Status s = adopt(c, std::move(it->second), space, lateDiagnostics); !s) return s;
    }
    return Status::ok();
}

std::function<SpaceSource::ReadAhead()> SpaceSource::readAhead(const std::vector<ChunkCoord>& cs) const {
    std::vector<std::pair<ChunkCoord, std::string>> files;
    for (ChunkCoord c : cs) files.emplace_back(c, chunks_.at(c).path);
    return [files = std::move(files)] {
        ReadAhead read;
        for (const auto& [c, path] : files) {
            if (stopRequested()) break;  // the rest read by load(), or not at all
            std::vector<Diagnostic> ignored;  // the scan (or the plan) gave these
            read.emplace(c, readChunkFile(path, c, ignored));
        }
        return read;
    };
}

// The rest of load() once chunk `c`'s file is read: its resources resolved, checked against
// the scan (or the plan), put into `space`.
Status SpaceSource::adopt(ChunkCoord c, Expected<ChunkFile> cf, Space& space, std::vector<Diagnostic>& lateDiagnostics) {
    if (!cf) return cf.error();
    ChunkEntry& entry = chunks_.at(c);
    // A planned source's first load stands for the scan: the plan's summary is checked
    // below, and these bytes are what a later load and the write compare with.
    const bool firstPlannedLoad = planned_ && loadedOnce_.insert(c).second;
    if (firstPlannedLoad) entry.contentHash = cf->contentHash;
    const bool edited = cf->contentHash != entry.contentHash;
    // The bake writes a chunk only while it holds the bytes the scan read: an edit made
    // since is kept (the bake refuses the chunk with a warning), whatever it now says.
    cf->contentHash = entry.contentHash;
    std::vector<Diagnostic> warnings;
    if (Status s = resolve(*cf, true, warnings); !s) return s;
    if (firstPlannedLoad)
        if (Status s = checkAgainstPlan(c, *cf); !s) return s;
    if (edited) lateDiagnostics.insert(lateDiagnostics.end(), warnings.begin(), warnings.end());
    space.chunks[c] = std::move(*cf);
    return Status::ok();
}

std::vector<std::shared_ptr<const Mesh>> SpaceSource::unload(ChunkCoord c, Space& space, TerrainMeshes& terrainMeshes) {
    space.chunks.erase(c);
    std::vector<std::shared_ptr<const Mesh>> gone;
    for (auto it = liveMeshes_.begin(); it != liveMeshes_.end();) {
        if (it->second.use_count() == 1) {  // only this map holds it: no loaded object uses it
            gone.push_back(std::move(it->second));
            it = liveMeshes_.erase(it);
        } else {
            ++it;
        }
    }
    for (auto it = liveTerrains_.begin(); it != liveTerrains_.end();) {
        if (it->second.use_count() == 1) {
            if (auto t = terrainMeshes.find(it->second.get()); t != terrainMeshes.end()) {
                gone.push_back(std::move(t->second));
                terrainMeshes.erase(t);
            }
            it = liveTerrains_.erase(it);
        } else {
            ++it;
        }
    }
    return gone;
}

WindowSequence::WindowSequence(SpaceSource& source, std::vector<ChunkCoord> centres, const WindowPlanner& planner)
    : source_(source), planner_(planner), centres_(std::move(centres)) {
    for (size_t k = 0; k < centres_.size(); ++k) {
        // Planning every window of a large world takes seconds; once a stop is requested the
        // sequence is left incomplete (enter() refuses to go on: SpaceSource::load).
        if (stopRequested()) break;
        for (ChunkCoord c : window(k)) lastUse_[c] = k;
    }
}

std::vector<ChunkCoord> WindowSequence::window(size_t k) const { return planner_.plan(centres_[k]).chunks; }

std::vector<ChunkCoord> WindowSequence::missing(size_t k, const Space& space) const {
    std::vector<ChunkCoord> out;
    for (ChunkCoord c : window(k))
        if (!space.chunks.count(c)) out.push_back(c);
    return out;
}

WindowSequence::~WindowSequence() {
    if (ahead_.valid()) ahead_.wait();
}

void WindowSequence::readAhead(size_t k, const Space& space) {
    if (k >= centres_.size() || ahead_.valid()) return;
    const std::vector<ChunkCoord> next = missing(k, space);
    if (next.empty()) return;
    aheadFor_ = k;
    ahead_ = std::async(std::launch::async, source_.readAhead(next));
}

Status WindowSequence::enter(size_t k, Space& space, std::vector<Diagnostic>& lateDiagnostics) {
    SpaceSource::ReadAhead ahead;
    if (ahead_.valid()) {
        ahead = ahead_.get();  // for another window (one skipped: resumed), simply unused
        if (aheadFor_ != k) ahead.clear();
    }
    if (Status s = source_.load(missing(k, space), space, lateDiagnostics, std::move(ahead)); !s) return s;
    peak_ = std::max(peak_, space.chunks.size());
    return Status::ok();
}

std::vector<std::shared_ptr<const Mesh>> WindowSequence::leave(size_t k, Space& space, TerrainMeshes& terrainMeshes) {
    std::vector<std::shared_ptr<const Mesh>> gone;
    for (ChunkCoord c : window(k))
        if (auto last = lastUse_.find(c); last != lastUse_.end() && last->second == k && space.chunks.count(c)) {
            std::vector<std::shared_ptr<const Mesh>> g = source_.unload(c, space, terrainMeshes);
            gone.insert(gone.end(), g.begin(), g.end());
        }
    return gone;
}

std::vector<std::string> Space::inputFiles() const {
    std::set<std::string> files{(fs::path(settings.spaceDir) / "space.xml").string()};
    for (const auto& [coord, cf] : chunks) {
        files.insert(cf.path);
        for (const ChunkObject& o : cf.objects) {
            if (!o.resource.empty()) files.insert((fs::path(settings.resourceRoot) / o.resource).lexically_normal().string());
            if (o.mesh) files.insert(o.mesh->sourceFiles.begin(), o.mesh->sourceFiles.end());
            if (o.heightfield) files.insert(o.heightfield->sourceFiles.begin(), o.heightfield->sourceFiles.end());
        }
    }
    return {files.begin(), files.end()};
}

Expected<Space> loadSpace(const std::string& spaceDir, const std::string& resourceRootOverride,
                          const std::vector<ChunkCoord>* only) {
    Space space;
    Expected<SpaceSource> src = SpaceSource::read(spaceDir, resourceRootOverride, only, &space);
    if (!src) return src.error();
    space.settings = src->settings_;
    space.diagnostics = src->diagnostics_;
    return space;
}

}  // namespace shadowcull
