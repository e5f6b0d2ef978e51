// `shadowcull export`: masks from a bake's results into a copy of the glTF scene.
//
// The scene is parsed twice: once by the document layer (validation, the same checks as
// import) and once as an order-keeping JSON tree that is edited and written back. Only
// "extras.shadowcull" of nodes and of the root is added or replaced; binary chunks and
// external files are untouched.

#include "gltf/gltf_export.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include <nlohmann/json.hpp>
#include <tinyxml2.h>

#include "core/scene.h"
#include "gltf/glb_writer.h"
#include "gltf/gltf_import.h"
#include "io/chunk_writer.h"
#include "io/file_read.h"
#include "io/gltf_document.h"
#include "io/results_file.h"
#include "io/scene_reader.h"
#include "io/xml_message.h"
#include "util/format.h"

namespace shadowcull::gltf {

namespace {

namespace fs = std::filesystem;
using OrderedJson = nlohmann::ordered_json;

uint32_t readU32(const std::string& s, size_t at) {
    uint32_t v = 0;
    for (size_t k = 0; k < 4; ++k) v |= uint32_t(uint8_t(s[at + k])) << (8 * k);
    return v;
}

// The scene file split into its JSON text and the chunks after it (GLB), or the JSON text
// alone (.gltf). The document layer has validated the container already.
struct SceneFile {
    bool glb = false;
    std::string jsonText;
    std::vector<std::pair<uint32_t, std::string>> chunks;  // GLB chunks after JSON, in order
};

SceneFile splitScene(const std::string& bytes, bool glb) {
    SceneFile f;
    f.glb = glb;
    if (!glb) {
        f.jsonText = bytes;
        return f;
    }
    const size_t length = readU32(bytes, 8);
    for (size_t at = 12; at + 8 <= length;) {
        const size_t n = readU32(bytes, at);
        const uint32_t type = readU32(bytes, at + 4);
        std::string data = bytes.substr(at + 8, n);
        if (at == 12) f.jsonText = std::move(data);
        else f.chunks.emplace_back(type, std::move(data));
        at += 8 + n;
    }
    return f;
}

struct SpaceLink {
    std::string identity;
    std::vector<long> lightNodes;  // per light in bit order: node, or -1 (--sun)
};

Expected<SpaceLink> readSpaceLink(const std::string& spaceDir) {
    const std::string file = (fs::path(spaceDir) / "space.xml").string();
    Expected<std::string> text = readRegularFile(file, "space.xml");
    if (!text) return text.error();
    tinyxml2::XMLDocument doc;
    if (doc.Parse(text->data(), text->size()) != tinyxml2::XML_SUCCESS)
        return makeError(ErrorKind::BadInput, file, doc.ErrorLineNum(), xmlParseProblem(doc));
    if (!doc.RootElement()) return makeError(ErrorKind::BadInput, file, 0, "no XML element in it");
    SpaceLink link;
    const tinyxml2::XMLElement* source = doc.RootElement()->FirstChildElement("gltfSource");
    if (!source || !source->Attribute("identity"))
        return makeError(ErrorKind::BadInput, file, 0,
                         "has no <gltfSource identity=...>: this space was not written by shadowcull import");
    link.identity = source->Attribute("identity");
    for (const tinyxml2::XMLElement* l = doc.RootElement()->FirstChildElement("light"); l; l = l->NextSiblingElement("light")) {
        const tinyxml2::XMLElement* g = l->FirstChildElement("gltf");
        int64_t node = -1;
        if (g && g->Attribute("node") && g->QueryInt64Attribute("node", &node) != tinyxml2::XML_SUCCESS)
            return makeError(ErrorKind::BadInput, file, g->GetLineNum(), "<gltf node=...> is not a node index");
        link.lightNodes.push_back(long(node));
    }
    return link;
}

struct Failure {
    Error error;
};

[[noreturn]] void fail(const std::string& file, const std::string& message, ErrorKind kind = ErrorKind::BadInput) {
    throw Failure{makeError(kind, file, 0, message)};
}

// Nodes the space placed (from the chunk files' uuids), to tell the user which of them the
// results do not cover.
std::set<size_t> spaceNodes(const std::string& spaceDir) {
    std::set<size_t> nodes;
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(spaceDir, ec)) {
        const std::optional<ChunkCoord> c = parseChunkName(e.path().filename().string());
        if (!c) continue;
        std::vector<Diagnostic> ignored;
        Expected<ChunkFile> cf = readChunkFile(e.path().string(), *c, ignored);
        if (!cf) continue;
        for (const ChunkObject& o : cf->objects)
            if (std::optional<size_t> n = nodeFromUuid(o.uuid)) nodes.insert(*n);
    }
    return nodes;
}

// Through the one atomic writer (io/chunk_writer.h): its temporary is created with O_EXCL
// and O_NOFOLLOW (a link planted at a predictable name is never written through), synced,
// renamed, and removed by the signal handler if the process ends meanwhile.
void writeAtomically(const std::string& path, const std::string& bytes) {
    if (Status s = writeFileAtomic(path, bytes); !s) fail(path, s.error().message + " (nothing written)", ErrorKind::Io);
}

// A .gltf names its buffers and images by paths relative to itself: written elsewhere
// it would lose them.
void checkRelativeUris(const OrderedJson& doc, const ExportOptions& opt) {
    std::error_code ec;
    const fs::path from = fs::weakly_canonical(fs::absolute(opt.scenePath).parent_path(), ec);
    const fs::path to = fs::weakly_canonical(fs::absolute(opt.outPath).parent_path(), ec);
    if (from == to) return;
    for (const char* array : {"buffers", "images"}) {
        auto a = doc.find(array);
        if (a == doc.end() || !a->is_array()) continue;
        for (const OrderedJson& item : *a) {
            auto uri = item.find("uri");
            if (uri == item.end() || !uri->is_string()) continue;
            const std::string u = uri->get<std::string>();
            if (u.rfind("data:", 0) == 0 || u.find("://") != std::string::npos) continue;
            fail(opt.outPath, std::string("the scene's ") + array + " name files by relative path ('" + u +
                                  "'); write the exported .gltf in the scene's own directory (" + from.string() +
                                  ") or export a .glb scene");
        }
    }
}

// One entry of the root's extras.shadowcull.lights: what an engine needs to apply the bits
// as they were baked (docs/format.md, "glTF scenes"). The values are the bake's (the results
// file's lights); a results file older than these fields takes space.xml's, which the bake
// read. Where both say a value they must agree: a space whose lights changed since the bake
// would hand the engine parameters the masks were not baked for.
OrderedJson lightEntry(const results::LightRecord& baked, const Light& space, long node, const ExportOptions& opt) {
    const std::string who = "light " + std::to_string(baked.index) + " '" + baked.name + "'";
    auto value = [&](const char* key, const std::optional<double>& fromResults, double fromSpace) {
        if (fromResults && *fromResults != fromSpace)
            fail(opt.resultsPath, who + " was baked with " + key + " " + formatNumber(*fromResults) + " but " + opt.spaceDir +
                                      "/space.xml now says " + formatNumber(fromSpace) +
                                      ": the space changed since this bake; bake again, then export");
        return fromResults ? *fromResults : fromSpace;
    };
    OrderedJson entry;
    entry["node"] = node >= 0 ? OrderedJson(node) : OrderedJson(nullptr);
    entry["name"] = baked.name;
    entry["type"] = baked.type;
    entry["bias"] = value("bias", baked.bias, space.bias);
    entry["slopeBias"] = value("slopeBias", baked.slopeBias, space.slopeBias);
    entry["filterRadius"] = value("filterRadius", baked.filterRadius, space.filterRadius);
    entry["normalBias"] = value("normalBias", baked.normalBias, space.normalBias);
    if (space.type != LightType::Directional) entry["range"] = value("range", baked.range, space.range);
    if (space.type == LightType::Spot) entry["coneAngle"] = value("coneAngle", baked.coneAngle, space.coneHalfAngleDeg);
    // A light on a node is placed by the node (the engine composes it as it does the
    // meshes); --sun has no node, so its direction is written (world, the way light travels).
    if (node < 0 && space.type != LightType::Point) {
        const glm::dvec3 d = baked.direction ? *baked.direction : space.direction;
        if (baked.direction && *baked.direction != space.direction)
            fail(opt.resultsPath, who + " was baked with another direction than " + opt.spaceDir +
                                      "/space.xml now gives: the space changed since this bake; bake again, then export");
        entry["direction"] = OrderedJson::array({d.x, d.y, d.z});
    }
    return entry;
}

ExportReport run(const ExportOptions& opt) {
    Expected<GltfDocument> doc = GltfDocument::open(opt.scenePath);
    if (!doc) throw Failure{doc.error()};
    Expected<SpaceLink> link = readSpaceLink(opt.spaceDir);
    if (!link) throw Failure{link.error()};
    if (sceneIdentity(doc->json()) != link->identity)
        fail(opt.scenePath, "is not the scene " + opt.spaceDir +
                                " was imported from (its content differs from what import recorded in space.xml "
                                "<gltfSource>); export to the scene you imported");
    Expected<results::ResultsFile> res = results::readResultsFile(opt.resultsPath);
    if (!res) throw Failure{res.error()};
    if (res->lights.size() != link->lightNodes.size())
        fail(opt.resultsPath, "has " + std::to_string(res->lights.size()) + " lights but " + opt.spaceDir + "/space.xml has " +
                                  std::to_string(link->lightNodes.size()) + ": the results are of another space");

    const std::string wantExt = doc->isGlb() ? ".glb" : ".gltf";
    std::string ext = fs::path(opt.outPath).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != wantExt)
        fail(opt.outPath, "the scene is a " + wantExt + " file, so the copy must be one too (name it *" + wantExt + ")");

    Expected<std::string> bytes = readRegularFile(opt.scenePath, "glTF file");
    if (!bytes) throw Failure{bytes.error()};
    SceneFile scene = splitScene(*bytes, doc->isGlb());
    OrderedJson out = OrderedJson::parse(scene.jsonText);
    if (!scene.glb) checkRelativeUris(out, opt);
    OrderedJson& nodes = out["nodes"];

    ExportReport report;
    std::set<size_t> given;
    for (size_t ci = 0; ci < res->chunks.size(); ++ci) {
        const results::ChunkRecord& c = res->chunks[ci];
        for (size_t oi = 0; oi < c.objects.size(); ++oi) {
            const results::ObjectRecord& o = c.objects[oi];
            const std::string where = "chunks[" + std::to_string(ci) + "].objects[" + std::to_string(oi) + "]";
            if (o.kind != "model") fail(opt.resultsPath, where + ": a " + o.kind + " is not a glTF node");
            std::optional<size_t> n = nodeFromUuid(o.uuid);
            if (!n || *n >= doc->nodes().size() || !doc->nodes()[*n].mesh)
                fail(opt.resultsPath, where + ": uuid '" + o.uuid + "' names no mesh node of " + opt.scenePath);
            // The uuid also carries a hash of the node's name: results of another import
            // (another scene with the same node count) are caught here.
            if (o.uuid != nodeUuid(*n, doc->nodes()[*n].name))
                fail(opt.resultsPath, where + ": uuid '" + o.uuid + "' does not match " + gltfPath("nodes", *n) + " '" +
                                          doc->nodes()[*n].name + "' of " + opt.scenePath + ": the results are of another scene");
            if (!given.insert(*n).second) fail(opt.resultsPath, where + ": " + gltfPath("nodes", *n) + " appears twice");
            if (o.skipped) continue;  // no verdicts: the node keeps no extras (all shadows kept)
            const size_t primitives = doc->json()["meshes"][*doc->nodes()[*n].mesh]["primitives"].size();
            if (o.groups.size() != primitives)
                fail(opt.resultsPath, where + ": " + std::to_string(o.groups.size()) + " groups, but " + gltfPath("nodes", *n) +
                                          "'s mesh has " + std::to_string(primitives) + " primitives");
            OrderedJson& node = nodes[*n];
            if (node.contains("extras") && !node["extras"].is_object())
                fail(opt.scenePath, gltfPath("nodes", *n) + ".extras is not an object: no room for extras.shadowcull");
            OrderedJson groups = OrderedJson::array();
            for (const results::GroupRecord& g : o.groups) {
                groups.push_back(g.mask);
                for (size_t l = 0; l < res->lights.size(); ++l) report.culledBits += ((g.mask >> l) & 1u) ? 0 : 1;
                report.bits += res->lights.size();
            }
            node["extras"]["shadowcull"] = OrderedJson{{"mask", o.mask}, {"groups", groups}};
            ++report.nodes;
            report.primitives += o.groups.size();
        }
    }
    for (size_t n : spaceNodes(opt.spaceDir))
        if (!given.count(n)) ++report.unbakedNodes;

    Expected<SpaceSettings> settings = readSpaceSettings(opt.spaceDir, "");
    if (!settings) throw Failure{settings.error()};
    if (settings->lights.size() != res->lights.size())
        fail(opt.resultsPath, "has " + std::to_string(res->lights.size()) + " lights but " + opt.spaceDir + "/space.xml has " +
                                  std::to_string(settings->lights.size()) + ": the results are of another space");
    OrderedJson lights = OrderedJson::array();
    for (size_t l = 0; l < res->lights.size(); ++l)
        lights.push_back(lightEntry(res->lights[l], settings->lights[l], link->lightNodes[l], opt));
    if (out.contains("extras") && !out["extras"].is_object())
        fail(opt.scenePath, "extras is not an object: no room for extras.shadowcull");
    out["extras"]["shadowcull"] = OrderedJson{{"lights", lights}};
    report.lights = res->lights.size();

    std::string written;
    if (scene.glb) {
        // The BIN chunk (and any other) is copied unchanged; the JSON chunk is compact.
        const std::string* bin = nullptr;
        std::vector<std::pair<uint32_t, std::string>> rest;
        for (const auto& ch : scene.chunks) {
            if (!bin && ch.first == 0x004E4942) bin = &ch.second;
            else rest.push_back(ch);
        }
        written = glbContainer(out.dump(), bin, rest);
    } else {
        written = out.dump(2) + "\n";
    }
    writeAtomically(opt.outPath, written);
    return report;
}

}  // namespace

Expected<ExportReport> exportMasks(const ExportOptions& opt) {
    try {
        return run(opt);
    } catch (const Failure& f) {
        return f.error;
    } catch (const nlohmann::json::exception& e) {
        return makeError(ErrorKind::BadInput, opt.scenePath, 0, std::string("unexpected JSON content: ") + e.what());
    }
}

}  // namespace shadowcull::gltf
