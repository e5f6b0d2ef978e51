// The results JSON of `shadowcull bake --results` (docs/cli.md, "Results JSON"): one model,
// one reader and one writer, so that bake, diff and the commands that will read a bake's
// results (merge, export, report) cannot drift apart on field names, omissions or checks.
// Plain data: JSON stays inside results_file.cpp.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "util/status.h"

namespace shadowcull::results {

// The "format" every results file names; anything else is refused before it is read.
inline constexpr const char* kFormat = "shadowcull-results";
// The only version this tool reads and writes.
inline constexpr int kVersion = 1;

// The ray that proves a 1 (core/verdict.h Witness): world metres.
// A world box {min, max}: what the pictures of `diff --html` draw for an object.
using BoxRecord = std::array<glm::dvec3, 2>;

struct WitnessRecord {
    glm::dvec3 origin{0.0}, direction{0.0}, p{0.0}, q{0.0};
    std::string receiver;  // label of the receiving object, with its group
    std::optional<BoxRecord> receiverBounds;  // the receiving object's box (left out: unknown)
};

// One (group, light) bit. `stage` and `reason` are empty when the file has none (an
// undecided bit); the writer then leaves them out, as it does `witness`.
struct BitRecord {
    int light = 0;  // from 1
    int bit = 1;    // as written: 0 only when proved
    std::string verdict, stage, reason;  // verdict: "kept", "culled" or "undecided"
    std::optional<WitnessRecord> witness;
    // Undecided bits: what each stage that looked saw ({stage, text}; "notes" in the file).
    std::vector<std::pair<std::string, std::string>> notes;
};

struct GroupRecord {
    int group = 0;                 // from 0, in order
    uint32_t mask = 0;             // the group's <shadow> bits
    std::optional<BoxRecord> bounds;  // the group's triangles (left out: none, or unknown)
    // The group's placed triangles as the engine draws them in a shadow pass (degenerate
    // ones too); left out by files older than this field.
    std::optional<uint64_t> triangles;
    std::vector<BitRecord> lights;  // [light - 1]
};

// A model or terrain element of the chunk. A skipped object (the bake could not use it)
// has no mask and no groups: the writer gives it element, kind, uuid and "skipped" only.
struct ObjectRecord {
    int element = 0;    // among the chunk root's model/terrain children
    std::string kind;   // "model" or "terrain"
    std::string uuid;   // empty: none (left out when written)
    bool skipped = false;
    uint32_t mask = 0;  // OR of the group masks
    std::vector<GroupRecord> groups;
};

// Shadow-pass work: casters (groups, one draw each) and their placed triangles.
struct WorkRecord {
    uint64_t casters = 0, triangles = 0;
};

// What the masks remove from one light's shadow pass (cli/savings.h computes it; "savings"
// in the file): every caster group of the baked chunks (`all`), those the engine's own
// run-time culling already skips (`engineCulls`: castsShadow false, beyond the range,
// outside the cone), those only this bake removes (`bakeCulls`, by deciding stage in
// `bakeCullsBy`) and those kept without a proof (`undecided`: savings still possible).
struct LightSavingsRecord {
    int light = 0;  // from 1
    WorkRecord all, engineCulls, bakeCulls, undecided;
    std::map<std::string, WorkRecord> bakeCullsBy;
};

struct ChunkRecord {
    std::string chunk;                   // file name, e.g. "0000ffffo.chunk"
    std::vector<std::string> simulated;  // effects the bake simulated for this chunk
    std::vector<ObjectRecord> objects;   // document order
    std::vector<LightSavingsRecord> savings;  // per light; empty: the file has none (older)
};

struct LightRecord {
    int index = 0;  // from 1, as the space lists the lights
    int bit = 0;    // index - 1: the bit of the masks
    std::string name, type;
    // The light as baked (so that `diff` can say what changed); each left out when the
    // type has none, or when the file is older than these fields.
    std::optional<glm::dvec3> position, direction;  // world; direction normalised
    std::optional<double> range, coneAngle;         // metres; spot half-angle, degrees
    std::optional<double> bias, slopeBias, filterRadius, normalBias;  // metres
};

// Counts over every bit of the file (what the bake's summary line prints).
struct Summary {
    uint64_t chunks = 0, groups = 0, bits = 0;
    uint64_t kept = 0, culled = 0;         // bits written 1 / 0
    uint64_t provedKept = 0;               // 1 with a witness (verdict "kept")
    uint64_t undecided = 0;                // 1 because nobody could decide
    std::map<std::string, uint64_t> culledBy;  // stage -> bits proved 0
    // Per light, over every chunk (left out by older files, and not derived for a file
    // without a "summary": cli/savings.h computes it from the groups' triangles).
    std::vector<LightSavingsRecord> savings;

    // Adds the bits of one more chunk (the counts above; not `savings`).
    void count(const ChunkRecord& chunk);
    // Adds the bits of one object of a chunk (count() without the chunk's own count).
    void countObject(const ObjectRecord& object);
};

// A shard's part of a bake (`bake --shard K/N`): what `merge` needs to check that the
// shards belong to one bake and cover the space once. Left out of a whole bake's file.
struct ShardRecord {
    int index = 0, count = 0;  // K of N, K from 1
    // Hash of everything every chunk's verdicts depend on (settings, lights, the options
    // that change verdicts, every chunk's objects and mesh content), 16 hex digits: equal
    // in every shard of one bake.
    std::string inputs;
    uint64_t spaceChunks = 0;          // chunk files in the space (all shards together)
    std::vector<std::string> assigned;  // this shard's chunks, grid order (baked or refused)
    // The first `spaceWarnings` warnings come from reading the space, the same in every
    // shard; the rest are this shard's own (a chunk not written).
    uint64_t spaceWarnings = 0;
};

struct ResultsFile {
    int version = kVersion;
    std::string space;  // the space directory as given to the bake
    std::vector<LightRecord> lights;
    std::vector<ChunkRecord> chunks;  // grid order, as baked
    Summary summary;
    std::vector<std::string> warnings;  // "file:line: message"
    std::optional<ShardRecord> shard;   // only in a shard's file
};

// The summary the bake writes for these chunks. The reader uses it for a file without a
// "summary" (written by hand): the counts are derived data, never guessed.
Summary summarize(const std::vector<ChunkRecord>& chunks);

// Reads the file at `path` (a regular file only: io/file_read.h) and parses it.
Expected<ResultsFile> readResultsFile(const std::string& path);

// Parses a results file's text; `path` is only used in messages. Errors are BadInput and
// name the file: with the line for malformed JSON, with the JSON path of the part being read
// for bad content ("path: malformed results at chunks[0].objects[2].groups[1]: ...").
// Checked: format and version, integers (JSON integers within the field's range), groups
// and lights in order, no chunk twice. Fields the writer always writes but that
// a reader can do without are optional: "space" (empty), a light's "index" and "bit" (its
// position), "simulated" and "warnings" (none), "summary" (summarize()); when present they
// must have the right type.
Expected<ResultsFile> parseResults(const std::string& path, const std::string& text);

// The file's text, exactly as `bake --results` writes it: pretty-printed with an indent of
// one space, keys sorted, fields left out as the structs above say, ending with a newline.
// Deterministic: the same model gives the same bytes.
std::string writeResults(const ResultsFile& file);

// Pieces of writeResults' text, for a writer that streams one chunk (or one object) at a
// time instead of holding the whole model: "chunks" is the first key of the file (keys are
// sorted), so the file is resultsHead(), then per chunk "\n" (first) or ",\n" (others)
// and chunkJson(chunk), then resultsTail(file, anyChunk) with the lights, summary and
// warnings, which are only known at the end. writeResults is built exactly so.
//
// One chunk as it stands in the "chunks" array (indented for that depth, no separator):
std::string chunkJson(const ChunkRecord& chunk);
// chunkJson in pieces, and built exactly so: chunkOpenJson(chunk.chunk), then per object
// "\n" (first) or ",\n" (others) and chunkObjectJson(object), then chunkCloseJson(chunk,
// anyObject) with "simulated" and "savings" (the objects of `chunk` are not used).
std::string chunkOpenJson(const std::string& chunk);
std::string chunkObjectJson(const ObjectRecord& object);
std::string chunkCloseJson(const ChunkRecord& chunk, bool anyObject);
// One chunk back from chunkJson's text (kept by `bake --resume` for the chunks it skips),
// read by the same reader as a whole file; `path` is only used in messages.
Expected<ChunkRecord> parseChunkJson(const std::string& path, const std::string& text);
// One object back from chunkObjectJson's text (or any JSON text of one object), read by the
// whole-file reader's checks on an object; `path` is only used in messages.
Expected<ObjectRecord> parseObjectJson(const std::string& path, const std::string& text);
// The opening of the file and of the "chunks" array.
std::string resultsHead();
// Everything after the last chunk; `anyChunk`: whether a chunk was written (the chunks of
// `file` are not used).
std::string resultsTail(const ResultsFile& file, bool anyChunk);

}  // namespace shadowcull::results
