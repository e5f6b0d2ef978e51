// A sharded bake's plan on disk (io/shard_plan.h).

#include "io/shard_plan.h"

#include <algorithm>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "io/chunk_writer.h"
#include "io/file_read.h"
#include "io/json_integer.h"
#include "util/hash.h"
#include "util/stop_request.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace shadowcull {

namespace {

constexpr const char* kPlanFormat = "shadowcull-plan";
constexpr const char* kShardFormat = "shadowcull-plan-shard";
constexpr const char* kInputsFormat = "shadowcull-plan-inputs";
constexpr int kVersion = 1;

json vec(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

glm::dvec3 vecOf(const json& j) { return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()}; }

// Hex digits only: stoull alone would take " 1", "-1" (as ffff...) and "0x1" too.
uint64_t hexOf(const json& j) {
    const std::string s = j.get<std::string>();
    if (s.empty() || s.size() > 16 || s.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
        throw std::invalid_argument("not a hex hash: " + s);
    return std::stoull(s, nullptr, 16);
}

// A count, index or line: a JSON integer of at least `least` within T (integerIn: what
// get<T>() would do with 1e20 or -1 is undefined or a huge count).
template <class T>
T integerOf(const json& v, const char* what, T least) {
    const std::optional<T> n = integerIn<T>(v);
    if (!n || *n < least)
        throw std::invalid_argument(std::string(what) + " must be an integer from " + std::to_string(least) + ", not " + v.dump());
    return *n;
}

// A list field (a range-for over a string or a number would take it as a list of one).
const json& arrayAt(const json& j, const char* key) {
    const json& a = j.at(key);
    if (!a.is_array()) throw std::invalid_argument(std::string(key) + " must be a list, not " + a.dump());
    return a;
}

ChunkCoord coordOf(const json& j) {
    std::optional<ChunkCoord> c = parseChunkName(j.get<std::string>());
    if (!c) throw std::invalid_argument("not a chunk name: " + j.get<std::string>());
    return *c;
}

json headJson(const PlanHead& head) {
    const SpaceOutline& o = head.outline;
    json warnings = json::array();
    for (const Diagnostic& d : head.diagnostics) warnings.push_back({{"file", d.file}, {"line", d.line}, {"message", d.message}});
    return {{"format", kPlanFormat},
            {"version", kVersion},
            {"space", head.spaceDir},
            {"shards", head.shards},
            {"chunks", o.chunks},
            {"content", hexHash(o.contentHash)},
            {"listing", hexHash(o.listingHash)},
            {"settings", hexHash(o.settingsHash)},
            {"bounds", {{"min", vec(o.bounds.wsSpace.min)}, {"max", vec(o.bounds.wsSpace.max)}, {"overhang", o.bounds.overhang}}},
            {"shardChunks", head.shardChunks},
            {"warnings", std::move(warnings)}};
}

PlanHead headOf(const json& j) {
    PlanHead h;
    h.spaceDir = j.at("space").get<std::string>();
    h.shards = integerOf(j.at("shards"), "shards", 1);
    SpaceOutline& o = h.outline;
    o.chunks = integerOf<size_t>(j.at("chunks"), "chunks", 0);
    o.contentHash = hexOf(j.at("content"));
    o.listingHash = hexOf(j.at("listing"));
    o.settingsHash = hexOf(j.at("settings"));
    const json& b = j.at("bounds");
    o.bounds.wsSpace = Aabb{vecOf(b.at("min")), vecOf(b.at("max"))};
    o.bounds.overhang = b.at("overhang").get<double>();
    for (const json& n : arrayAt(j, "shardChunks")) h.shardChunks.push_back(integerOf<size_t>(n, "shardChunks", 0));
    for (const json& w : arrayAt(j, "warnings"))
        h.diagnostics.push_back({w.at("file").get<std::string>(), integerOf(w.at("line"), "line", 0), w.at("message").get<std::string>()});
    if (h.shardChunks.size() != size_t(h.shards)) throw std::invalid_argument("shardChunks does not list every shard");
    return h;
}

json shardJson(const PlanShard& shard, uint64_t planId) {
    json assigned = json::array(), chunks = json::array();
    for (ChunkCoord c : shard.assigned) assigned.push_back(chunkFileName(c));
    for (const auto& [c, e] : shard.chunks) {
        json bounds = e.wsBounds.empty() ? json(nullptr) : json::array({vec(e.wsBounds.min), vec(e.wsBounds.max)});
        chunks.push_back({{"chunk", chunkFileName(c)},
                          {"path", e.path},
                          {"objects", hexHash(e.objectsHash)},
                          {"text", hexHash(e.contentWithoutShadowsHash)},
                          {"usable", e.usableObjects},
                          {"bounds", std::move(bounds)}});
    }
    return {{"format", kShardFormat}, {"version", kVersion}, {"plan", hexHash(planId)}, {"shard", shard.index},
            {"of", shard.count},      {"assigned", std::move(assigned)}, {"chunks", std::move(chunks)}};
}

PlanShard shardOf(const json& j) {
    PlanShard s;
    s.index = integerOf(j.at("shard"), "shard", 1);
    s.count = integerOf(j.at("of"), "of", 1);
    for (const json& a : arrayAt(j, "assigned")) s.assigned.push_back(coordOf(a));
    // A chunk assigned twice would be baked twice, and its results file refused by merge.
    if (std::adjacent_find(s.assigned.begin(), s.assigned.end(), [](ChunkCoord a, ChunkCoord b) { return !(a < b); }) !=
        s.assigned.end())
        throw std::invalid_argument("the assigned chunks are not in grid order, each once");
    for (const json& c : arrayAt(j, "chunks")) {
        ChunkEntry e;
        e.path = c.at("path").get<std::string>();
        e.objectsHash = hexOf(c.at("objects"));
        e.contentWithoutShadowsHash = hexOf(c.at("text"));
        e.usableObjects = integerOf<size_t>(c.at("usable"), "usable", 0);
        if (const json& b = c.at("bounds"); !b.is_null()) e.wsBounds = Aabb{vecOf(b.at(0)), vecOf(b.at(1))};
        s.chunks.emplace(coordOf(c.at("chunk")), std::move(e));
    }
    for (ChunkCoord a : s.assigned)
        if (!s.chunks.count(a)) throw std::invalid_argument("an assigned chunk has no summary: " + chunkFileName(a));
    return s;
}

// A plan file's JSON, its format checked; the parse's own errors name the file.
// `id`, when given, gets the hash of the file's bytes (what shard files name).
Expected<json> readPlanJson(const std::string& path, const char* format, uint64_t* id = nullptr) {
    std::error_code ec;
    if (!fs::exists(path, ec))
        return makeError(ErrorKind::MissingResource, path, 0, "no such plan file (made by: shadowcull plan SPACE --shards N --plan DIR)");
    Expected<std::string> text = readRegularFile(path, "plan file", ErrorKind::BadInput);
    if (!text) return text.error();
    if (id) *id = Hasher().str(*text).value();
    json j = json::parse(*text, nullptr, false);
    // Compared as JSON values: value("format", "") would throw on a format that is no string.
    if (j.is_discarded() || !j.is_object() || j.value("format", json()) != format)
        return makeError(ErrorKind::BadInput, path, 0, std::string("not a ") + format + " file");
    if (j.value("version", json()) != kVersion)
        return makeError(ErrorKind::BadInput, path, 0, "a plan of another version of shadowcull: plan again");
    return j;
}

}  // namespace

std::string ShardPlanFiles::planPath(const std::string& dir) { return (fs::path(dir) / "plan.json").string(); }

std::string ShardPlanFiles::inputsPath(const std::string& dir) { return (fs::path(dir) / "inputs.json").string(); }

std::string ShardPlanFiles::shardPath(const std::string& dir, int index, int count) {
    return (fs::path(dir) / ("shard-" + std::to_string(index) + "-of-" + std::to_string(count) + ".json")).string();
}

Status writeShardPlan(const std::string& dir, const PlanHead& head, const std::vector<PlanShard>& shards,
                      const std::vector<std::string>& resourceFiles) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) return makeError(ErrorKind::Io, dir, 0, "cannot create the plan directory: " + ec.message());
    const std::string headText = headJson(head).dump() + "\n";
    const uint64_t planId = Hasher().str(headText).value();
    for (const PlanShard& s : shards) {
        // A signal stops between files; the files written name a plan.json that was never
        // written, and a shard refuses them (StalePlan).
        if (Status st = stopStatus(); !st) return st;
        if (Status st = writeFileAtomic(ShardPlanFiles::shardPath(dir, s.index, s.count), shardJson(s, planId).dump() + "\n"); !st)
            return st;
    }
    const json inputs{{"format", kInputsFormat}, {"version", kVersion}, {"plan", hexHash(planId)}, {"files", resourceFiles}};
    if (Status st = writeFileAtomic(ShardPlanFiles::inputsPath(dir), inputs.dump() + "\n"); !st) return st;
    return writeFileAtomic(ShardPlanFiles::planPath(dir), headText);
}

Expected<std::vector<std::string>> readPlanInputs(const std::string& dir, uint64_t planId) {
    const std::string path = ShardPlanFiles::inputsPath(dir);
    Expected<json> j = readPlanJson(path, kInputsFormat);
    if (!j) return j.error();
    try {
        if (hexOf(j->at("plan")) != planId)
            return makeError(ErrorKind::StalePlan, path, 0, "belongs to another plan than " + ShardPlanFiles::planPath(dir) + ": plan again");
        return j->at("files").get<std::vector<std::string>>();
    } catch (const std::exception& e) {
        return makeError(ErrorKind::BadInput, path, 0, std::string("malformed plan: ") + e.what());
    }
}

Expected<LoadedShardPlan> readShardPlan(const std::string& dir, int index, int count) {
    const std::string headPath = ShardPlanFiles::planPath(dir), shardPath = ShardPlanFiles::shardPath(dir, index, count);
    uint64_t planId = 0;
    Expected<json> head = readPlanJson(headPath, kPlanFormat, &planId);
    if (!head) return head.error();
    LoadedShardPlan out;
    try {
        out.head = headOf(*head);
        out.head.id = planId;
    } catch (const std::exception& e) {
        return makeError(ErrorKind::BadInput, headPath, 0, std::string("malformed plan: ") + e.what());
    }
    if (out.head.shards != count)
        return makeError(ErrorKind::BadInput, headPath, 0,
                         "a plan for " + std::to_string(out.head.shards) + " shards, not " + std::to_string(count) +
                             ": give --shard K/" + std::to_string(out.head.shards) + ", or plan again with --shards " +
                             std::to_string(count));
    Expected<json> shard = readPlanJson(shardPath, kShardFormat);
    if (!shard) return shard.error();
    try {
        // The shard file must be of this plan.json (a plan made again while shards ran
        // replaces them one by one).
        if (hexOf(shard->at("plan")) != planId)
            return makeError(ErrorKind::StalePlan, shardPath, 0, "belongs to another plan than " + headPath + ": plan again");
        out.shard = shardOf(*shard);
    } catch (const std::exception& e) {
        return makeError(ErrorKind::BadInput, shardPath, 0, std::string("malformed plan: ") + e.what());
    }
    if (out.shard.index != index || out.shard.count != count)
        return makeError(ErrorKind::BadInput, shardPath, 0, "holds another shard's plan");
    return out;
}

PlannedSpace plannedSpaceOf(const std::string& dir, LoadedShardPlan&& plan) {
    const uint64_t id = plan.head.id;
    PlannedSpace p{plan.head.spaceDir, plan.head.outline, std::move(plan.head.diagnostics), std::move(plan.shard.chunks), {}};
    p.otherInputs = [dir, id] { return readPlanInputs(dir, id); };
    return p;
}

}  // namespace shadowcull
