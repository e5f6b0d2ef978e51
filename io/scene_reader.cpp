// Readers for space.xml, chunk files, .model and .terrain resources
// (../shared/spec/scene-format.md). Every error names the file and line.

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <csetjmp>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <string_view>

#include <glm/geometric.hpp>
#include <png.h>
#include <tinyxml2.h>

#include "core/limits.h"
#include "core/scene.h"
#include "io/chunk_writer.h"
#include "io/file_read.h"
#include "io/mesh_load.h"
#include "io/scene_reader.h"
#include "io/xml_message.h"
#include "util/format.h"
#include "util/hash.h"
#include "util/nearest_name.h"

namespace fs = std::filesystem;

namespace shadowcull {

namespace {

std::string trim(const char* s) {
    if (!s) return {};
    std::string t(s);
    size_t a = t.find_first_not_of(" \t\r\n");
    if (a == std::string::npos) return {};
    size_t b = t.find_last_not_of(" \t\r\n");
    return t.substr(a, b - a + 1);
}

Error bad(const std::string& file, int line, const std::string& msg) {
    return makeError(ErrorKind::BadInput, file, line, msg);
}

// Whether `t` is a decimal number as every reader of the tool takes one (the OBJ reader's
// grammar): an optional sign, digits with an optional point (or a point and digits), an
// optional exponent. No hex or hex-float (strtod's "0x10" would be 16), no inf or nan.
bool isDecimalNumber(std::string_view t) {
    size_t i = 0;
    auto digits = [&] {
        const size_t from = i;
        while (i < t.size() && t[i] >= '0' && t[i] <= '9') ++i;
        return i - from;
    };
    if (i < t.size() && (t[i] == '+' || t[i] == '-')) ++i;
    size_t mantissa = digits();
    if (i < t.size() && t[i] == '.') {
        ++i;
        mantissa += digits();
    }
    if (mantissa == 0) return false;
    if (i < t.size() && (t[i] == 'e' || t[i] == 'E')) {
        ++i;
        if (i < t.size() && (t[i] == '+' || t[i] == '-')) ++i;
        if (digits() == 0) return false;
    }
    return i == t.size();
}

// The values an element accepts (core/limits.h), as its messages quote them: [-1e+10, 1e+10]
// for a position, (0, 100000] for a range.
struct Accepted {
    double low = -std::numeric_limits<double>::max();
    double high = std::numeric_limits<double>::max();
    bool aboveLow = false;  // the low bound itself is refused
    // The size beyond which a value is refused where it is parsed. A value within it but
    // below `low` (a bias of -0.25) is left to the caller, whose message names the light.
    double bound() const { return std::max(std::abs(low), std::abs(high)); }
};

Accepted within(double bound) { return {-bound, bound}; }
Accepted upTo(double high) { return {0.0, high}; }
Accepted aboveZeroUpTo(double high) { return {0.0, high, true}; }

// Parses `count` finite decimal numbers separated by white space, none larger than
// `accepted` allows; nothing else may follow.
Status parseNumbers(const std::string& file, const tinyxml2::XMLElement* e, double* out, int count,
                    const Accepted& accepted = {}) {
    std::string text = trim(e->GetText());
    const char* p = text.c_str();
    for (int k = 0; k < count; ++k) {
        char* end = nullptr;
        while (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r') ++p;
        const char* tokenEnd = p;
        while (*tokenEnd && *tokenEnd != ' ' && *tokenEnd != '\t' && *tokenEnd != '\n' && *tokenEnd != '\r') ++tokenEnd;
        if (tokenEnd != p && !isDecimalNumber(std::string_view(p, size_t(tokenEnd - p))))
            return bad(file, e->GetLineNum(),
                       "<" + std::string(e->Name()) + "> value '" + std::string(p, size_t(tokenEnd - p)) +
                           "' is not a decimal number (digits, an optional point and exponent: docs/format.md) in '" + text + "'");
        errno = 0;
        out[k] = std::strtod(p, &end);
        if (end == p)
            return bad(file, e->GetLineNum(),
                       "<" + std::string(e->Name()) + "> expects " + std::to_string(count) + " number(s), got '" + text + "'");
        if (errno == ERANGE && std::isinf(out[k]))
            return bad(file, e->GetLineNum(),
                       "<" + std::string(e->Name()) + "> value " + std::string(p, size_t(end - p)) +
                           " is too large to be a number here (more than 1.8e308) in '" + text + "'");
        if (!std::isfinite(out[k]))
            return bad(file, e->GetLineNum(), "<" + std::string(e->Name()) + "> has a non-finite value '" + text + "'");
        if (std::abs(out[k]) > accepted.bound())
            return bad(file, e->GetLineNum(),
                       "<" + std::string(e->Name()) + "> value " + formatExact(out[k]) + " is outside the accepted range " +
                           formatInterval(accepted.low, accepted.high, accepted.aboveLow) +
                           " (docs/format.md, accepted ranges)");
        p = end;
    }
    while (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r') ++p;
    if (*p != '\0')
        return bad(file, e->GetLineNum(), "<" + std::string(e->Name()) + "> has trailing text in '" + text + "'");
    return Status::ok();
}

// The message for the first child element of `parent` that repeats an earlier one (a
// name not in `repeatable`), and its line; nothing when none does. Which of two values
// would win is not for the tool to guess (tinyxml2 lookups take the first, loops the last).
std::optional<std::pair<int, std::string>> repeatedChild(const tinyxml2::XMLElement* parent,
                                                         std::initializer_list<const char*> repeatable = {}) {
    std::map<std::string, int> firstLine;
    for (const tinyxml2::XMLElement* c = parent->FirstChildElement(); c; c = c->NextSiblingElement()) {
        const std::string n = c->Name();
        if (std::any_of(repeatable.begin(), repeatable.end(), [&](const char* r) { return n == r; })) continue;
        if (auto [it, added] = firstLine.emplace(n, c->GetLineNum()); !added)
            return std::pair<int, std::string>{c->GetLineNum(), "<" + n + "> given again in <" + std::string(parent->Name()) +
                                                                     "> (first at line " + std::to_string(it->second) +
                                                                     "): give each value once"};
    }
    return std::nullopt;
}

// The elements each place holds and the attributes the reader takes
// (../shared/spec/scene-format.md; <gltfSource> and a light's <gltf> are written by import
// and read by export).
const std::vector<std::string> kSpaceElements = {"chunkSize", "neighbours", "terrainTolerance", "resourceRoot", "light",
                                                 "gltfSource"};
const std::vector<std::string> kLightElements = {"name",  "type",      "direction",    "position",   "range", "coneAngle",
                                                 "bias", "slopeBias", "filterRadius", "normalBias", "gltf"};
const std::vector<std::string> kModelResourceElements = {"visual", "primitiveGroup"};
const std::vector<std::string> kTerrainResourceElements = {"heights", "minHeight", "maxHeight"};
const std::vector<std::string> kTransformElements = {"row0", "row1", "row2", "row3"};
const std::vector<std::string> kNeighboursAttributes = {"left", "right", "top", "bottom"};
const std::vector<std::string> kPrimitiveGroupAttributes = {"index", "alphaTest", "doubleSided"};

// Another program's data: a namespaced name (<engine:lod>, engine:lod="2") is not the
// reader's to know, nor a namespace declaration (xmlns, xmlns:engine).
bool isForeignName(const std::string& name) { return name.find(':') != std::string::npos || name == "xmlns"; }

// An element or attribute the reader does not know, with its line and a message naming the
// nearest known name.
struct UnknownName {
    int line = 0;
    std::string message;
    bool misspelt = false;  // near enough to a known name to be a misspelling of it
};

// `given`, one of `known` or not, as a message writes it: <filterRadius>, or alphaTest=.
std::string spelt(const std::string& name, bool attribute) { return attribute ? name + "=" : "<" + name + ">"; }

// The message for `given` (an element in <parent>, or an attribute of it), unknown there:
// "did you mean <filterRadius>?" for a misspelling, else what <parent> holds.
UnknownName unknownName(const std::string& given, const tinyxml2::XMLElement* parent, int line,
                        const std::vector<std::string>& known, bool attribute) {
    const std::string nearest = nearestName(given, known);
    const bool misspelt = looksLikeMisspelling(given, nearest);
    const std::string where = "<" + std::string(parent->Name()) + ">";
    std::string hint = "did you mean " + spelt(nearest, attribute) + "?";
    if (!misspelt) {
        std::string list;
        for (const std::string& k : known)
            list += (list.empty() ? "" : &k == &known.back() ? " and " : ", ") + spelt(k, attribute);
        hint = where + (attribute ? " takes " : " holds ") + list + "; another program's data may go in a namespaced " +
               (attribute ? "attribute" : "element") + ", e.g. " + spelt("engine:" + given, attribute);
    }
    const std::string what = attribute ? "unknown attribute " + spelt(given, true) + " of "
                                       : "unknown element " + spelt(given, false) + " in ";
    return {line, what + where + " (" + hint + ")", misspelt};
}

// Each child element of `parent` that is none of `known` and not another program's.
std::vector<UnknownName> unknownChildren(const tinyxml2::XMLElement* parent, const std::vector<std::string>& known) {
    std::vector<UnknownName> unknown;
    for (const tinyxml2::XMLElement* c = parent->FirstChildElement(); c; c = c->NextSiblingElement())
        if (const std::string n = c->Name(); !isForeignName(n) && std::find(known.begin(), known.end(), n) == known.end())
            unknown.push_back(unknownName(n, parent, c->GetLineNum(), known, false));
    return unknown;
}

// Each attribute of `e` that is none of `known` and not another program's.
std::vector<UnknownName> unknownAttributes(const tinyxml2::XMLElement* e, const std::vector<std::string>& known) {
    std::vector<UnknownName> unknown;
    for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next())
        if (const std::string n = a->Name(); !isForeignName(n) && std::find(known.begin(), known.end(), n) == known.end())
            unknown.push_back(unknownName(n, e, e->GetLineNum(), known, true));
    return unknown;
}

// space.xml is refused at its first unknown name: one ignored there is a setting baked as
// its default (a misspelt <filterRadius> leaves the filter at 0 and culls shadows the
// engine's filter draws), a light left out (every later light's bit shifts) or a grid of
// the wrong size.
Status refuseUnknown(const std::string& file, const std::vector<UnknownName>& unknown) {
    if (unknown.empty()) return Status::ok();
    return bad(file, unknown.front().line,
               unknown.front().message + "; the bake stops rather than ignore it (docs/format.md, \"Unknown elements\")");
}

// In a resource, a misspelt name is an error of the resource (its objects are skipped): a
// lost <primitiveGroup alphaTest="true"> bakes the leaves opaque. Any other unknown name is
// a warning (exit 1) and ignored: what a resource needs is looked up by name, so an extra
// element or attribute cannot change what is baked.
Status checkResourceNames(const std::string& file, const std::vector<UnknownName>& unknown, std::vector<Diagnostic>* warnings) {
    for (const UnknownName& u : unknown) {
        if (u.misspelt) return bad(file, u.line, u.message);
        if (warnings) warnings->push_back({file, u.line, u.message + "; ignored"});
    }
    return Status::ok();
}

Status parseVec3(const std::string& file, const tinyxml2::XMLElement* e, glm::dvec3& v, const Accepted& accepted = {}) {
    double d[3];
    Status s = parseNumbers(file, e, d, 3, accepted);
    if (s) v = glm::dvec3(d[0], d[1], d[2]);
    return s;
}

Status parseDouble(const std::string& file, const tinyxml2::XMLElement* e, double& v, const Accepted& accepted = {}) {
    return parseNumbers(file, e, &v, 1, accepted);
}

Status parseBool(const std::string& file, const tinyxml2::XMLElement* e, bool& v) {
    std::string t = trim(e->GetText());
    std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (t == "true" || t == "1") v = true;
    else if (t == "false" || t == "0") v = false;
    else return bad(file, e->GetLineNum(), "<" + std::string(e->Name()) + "> expects true or false, got '" + t + "'");
    return Status::ok();
}

// Loads an XML file (a regular file only: io/file_read.h); a syntax error names the line
// tinyxml2 reports. `contentHash`, when given, receives the hash of the bytes parsed.
Status loadXml(const std::string& path, tinyxml2::XMLDocument& doc, const std::string& what,
               ErrorKind missingKind = ErrorKind::MissingResource, uint64_t* contentHash = nullptr) {
    Expected<std::string> text = readRegularFile(path, what, missingKind, size_t(1) << 30);
    if (!text) return text.error();
    if (contentHash) *contentHash = Hasher().str(*text).value();
    if (text->find('\0') != std::string::npos)
        return bad(path, 1 + int(std::count(text->begin(), text->begin() + std::ptrdiff_t(text->find('\0')), '\n')),
                   "binary data (a NUL byte) in an XML file");
    tinyxml2::XMLError rc = doc.Parse(text->data(), text->size());
    if (rc != tinyxml2::XML_SUCCESS) return bad(path, doc.ErrorLineNum(), xmlParseProblem(doc));
    if (!doc.RootElement()) return bad(path, 1, "no root element");
    // tinyxml2 reads a second root element, or an end tag after the root, without a word.
    return checkXmlStructure(*text, path);
}

Expected<Light> readLight(const std::string& file, const tinyxml2::XMLElement* le) {
    Light L;
    L.line = le->GetLineNum();
    bool hasType = false, hasRange = false, hasCone = false, hasPosition = false;
    // The element each value came from, for messages that point at the line to fix.
    const tinyxml2::XMLElement *directionElement = nullptr, *rangeElement = nullptr, *coneElement = nullptr;
    std::vector<std::pair<const tinyxml2::XMLElement*, double*>> distances;  // bias, slopeBias, filterRadius, normalBias
    if (auto again = repeatedChild(le)) return bad(file, again->first, again->second);
    if (Status s = refuseUnknown(file, unknownChildren(le, kLightElements)); !s) return s.error();
    for (const tinyxml2::XMLElement* e = le->FirstChildElement(); e; e = e->NextSiblingElement()) {
        std::string n = e->Name();
        Status s;
        if (n == "name") L.name = trim(e->GetText());
        else if (n == "type") {
            std::string t = trim(e->GetText());
            hasType = true;
            if (t == "directional") L.type = LightType::Directional;
            else if (t == "point") L.type = LightType::Point;
            else if (t == "spot") L.type = LightType::Spot;
            else return bad(file, e->GetLineNum(), "unknown light type '" + t + "' (directional, point or spot)");
        } else if (n == "direction") { s = parseVec3(file, e, L.direction); directionElement = e; }
        else if (n == "position") { s = parseVec3(file, e, L.position, within(limits::kMaxWorldCoordinate)); hasPosition = true; }
        else if (n == "range") { s = parseDouble(file, e, L.range, aboveZeroUpTo(limits::kMaxLength)); hasRange = true; rangeElement = e; }
        else if (n == "coneAngle") { s = parseDouble(file, e, L.coneHalfAngleDeg); hasCone = true; coneElement = e; }
        else if (n == "bias") { s = parseDouble(file, e, L.bias, upTo(limits::kMaxLength)); distances.emplace_back(e, &L.bias); }
        else if (n == "slopeBias") { s = parseDouble(file, e, L.slopeBias, upTo(limits::kMaxLength)); distances.emplace_back(e, &L.slopeBias); }
        else if (n == "filterRadius") { s = parseDouble(file, e, L.filterRadius, upTo(limits::kMaxLength)); distances.emplace_back(e, &L.filterRadius); }
        else if (n == "normalBias") { s = parseDouble(file, e, L.normalBias, upTo(limits::kMaxLength)); distances.emplace_back(e, &L.normalBias); }
        if (!s) return s.error();
    }
    const std::string who = "light '" + L.name + "'";
    auto at = [&](const tinyxml2::XMLElement* e) { return e ? e->GetLineNum() : L.line; };
    if (!hasType) return bad(file, L.line, who + " has no <type> (directional, point or spot)");
    if (L.type != LightType::Point) {
        if (!directionElement) return bad(file, L.line, who + " (" + lightTypeName(L.type) + ") needs a <direction>");
        // Scale by the largest component first: (1e308, -1e308, 1e308) and (1e-300, 0, 0)
        // are directions too, and their length would overflow or underflow.
        const double big = std::max({std::abs(L.direction.x), std::abs(L.direction.y), std::abs(L.direction.z)});
        if (!(big > 0.0))
            return bad(file, at(directionElement),
                       who + ": <direction> '" + trim(directionElement->GetText()) +
                           "' has no length (every component is 0, or too small to tell from 0); give the way the "
                           "light shines, e.g. 0 -1 0");
        L.direction /= big;
        L.direction /= glm::length(L.direction);
    }
    if (L.type != LightType::Directional) {
        if (!hasPosition) return bad(file, L.line, who + " (" + lightTypeName(L.type) + ") needs a <position>");
        if (!hasRange) return bad(file, L.line, who + " (" + lightTypeName(L.type) + ") needs a <range> (metres, > 0)");
        if (!(L.range > 0.0))
            return bad(file, at(rangeElement), who + ": <range> is " + formatExact(L.range) + "; it must be more than 0 (metres)");
    }
    if (L.type == LightType::Spot) {
        if (!hasCone) return bad(file, L.line, who + " (spot) needs a <coneAngle> (half-angle, degrees, in (0, 90])");
        if (!(L.coneHalfAngleDeg > 0.0) || L.coneHalfAngleDeg > 90.0)
            return bad(file, at(coneElement), who + ": <coneAngle> is " + formatExact(L.coneHalfAngleDeg) +
                                                  "; the half-angle must be more than 0 and at most 90 degrees");
    }
    for (const auto& [e, value] : distances)
        if (*value < 0)
            return bad(file, e->GetLineNum(), who + ": <" + e->Name() + "> is " + formatExact(*value) +
                                                  "; it must not be negative (metres)");
    return L;
}

}  // namespace

Expected<SpaceSettings> readSpaceSettings(const std::string& spaceDir, const std::string& resourceRootOverride) {
    SpaceSettings st;
    st.spaceDir = spaceDir;
    const std::string file = (fs::path(spaceDir) / "space.xml").string();
    tinyxml2::XMLDocument doc;
    if (Status s = loadXml(file, doc, "space.xml", ErrorKind::BadInput); !s) return s.error();
    std::string resourceRoot;
    if (auto again = repeatedChild(doc.RootElement(), {"light"})) return bad(file, again->first, again->second);
    if (Status s = refuseUnknown(file, unknownChildren(doc.RootElement(), kSpaceElements)); !s) return s.error();
    for (const tinyxml2::XMLElement* e = doc.RootElement()->FirstChildElement(); e; e = e->NextSiblingElement()) {
        std::string n = e->Name();
        Status s;
        if (n == "chunkSize") {
            s = parseDouble(file, e, st.chunkSize);
            if (s && !(st.chunkSize >= limits::kMinChunkSize && st.chunkSize <= limits::kMaxChunkSize))
                return bad(file, e->GetLineNum(), "<chunkSize> " + formatExact(st.chunkSize) + " is outside the accepted range " +
                                                      formatInterval(limits::kMinChunkSize, limits::kMaxChunkSize) + " m");
        } else if (n == "terrainTolerance") {
            s = parseDouble(file, e, st.terrainTolerance, upTo(limits::kMaxLength));
            if (s && st.terrainTolerance < 0) return bad(file, e->GetLineNum(), "<terrainTolerance> is " + formatExact(st.terrainTolerance) +
                                                                           "; it must not be negative (metres)");
        } else if (n == "resourceRoot") {
            resourceRoot = trim(e->GetText());
        } else if (n == "neighbours") {
            auto attr = [&](const char* a, int& v) -> Status {
                const char* t = e->Attribute(a);
                if (!t) return Status::ok();
                char* end = nullptr;
                long x = std::strtol(t, &end, 10);
                if (end == t || *end || x < 0 || x > limits::kMaxNeighbours)
                    return bad(file, e->GetLineNum(), std::string("<neighbours ") + a + "=\"" + t +
                                                          "\"> must be a whole number from 0 to " + std::to_string(limits::kMaxNeighbours));
                v = int(x);
                return Status::ok();
            };
            if (Status us = refuseUnknown(file, unknownAttributes(e, kNeighboursAttributes)); !us) return us.error();
            if (e->FirstAttribute()) {
                for (auto [a, v] : {std::pair<const char*, int*>{"left", &st.neighbours.left}, {"right", &st.neighbours.right},
                                    {"top", &st.neighbours.top}, {"bottom", &st.neighbours.bottom}})
                    if (Status as = attr(a, *v); !as) return as.error();
            }
            if (!trim(e->GetText()).empty()) {
                double d = 0;
                s = parseDouble(file, e, d);
                if (s && (d < 0 || d > limits::kMaxNeighbours || d != std::floor(d)))
                    return bad(file, e->GetLineNum(), "<neighbours> is " + formatExact(d) + "; it must be a whole number from 0 to " +
                                                          std::to_string(limits::kMaxNeighbours));
                if (s) st.neighbours = Neighbours{int(d), int(d), int(d), int(d)};
            }
        } else if (n == "light") {
            if (int(st.lights.size()) == kMaxLights)
                return bad(file, e->GetLineNum(), "more than 32 lights (a mask has 32 bits)");
            Expected<Light> L = readLight(file, e);
            if (!L) return L.error();
            st.lights.push_back(*L);
        }
        if (!s) return s.error();
    }
    if (!resourceRootOverride.empty()) resourceRoot = resourceRootOverride;
    if (resourceRoot.empty()) st.resourceRoot = spaceDir;
    else if (fs::path(resourceRoot).is_absolute() || !resourceRootOverride.empty()) st.resourceRoot = resourceRoot;
    else st.resourceRoot = (fs::path(spaceDir) / resourceRoot).string();
    // One error up front instead of one warning per object that names a resource.
    std::error_code ec;
    const bool isDir = fs::is_directory(st.resourceRoot, ec);
    if (ec || !isDir) {
        const std::string why = ec ? ec.message() : fs::exists(st.resourceRoot, ec) ? "not a directory" : "no such directory";
        return makeError(ErrorKind::MissingResource, resourceRootOverride.empty() ? file : st.resourceRoot, 0,
                         "resource root " + st.resourceRoot + " cannot be used: " + why +
                             (resourceRootOverride.empty() ? " (<resourceRoot> of space.xml)" : " (--res)"));
    }
    return st;
}

namespace {

// ChunkFile::contentWithoutShadowsHash: every node in document order, skipping the <shadow>
// children of the root's <model> and <terrain> elements (the only ones the chunk writer
// rewrites) and whitespace-only text. An element hashes its name, its attributes in order
// and its children between an open and a close marker, so `<a/>` and `<a></a>` are equal
// (the writer turns the first into the second) while nesting still counts.
void hashWithoutShadows(const tinyxml2::XMLNode* node, int depth, Hasher& h) {
    for (const tinyxml2::XMLNode* n = node->FirstChild(); n; n = n->NextSibling()) {
        if (const tinyxml2::XMLElement* e = n->ToElement()) {
            const std::string name = e->Name();
            const bool objectChild = depth == 2 && name == "shadow";
            if (objectChild) {
                const tinyxml2::XMLElement* parent = node->ToElement();
                const std::string parentName = parent ? parent->Name() : "";
                if (parentName == "model" || parentName == "terrain") continue;
            }
            h.pod(uint8_t('<')).str(name);
            for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next())
                h.pod(uint8_t('=')).str(a->Name()).str(a->Value());
            hashWithoutShadows(e, depth + 1, h);
            h.pod(uint8_t('>'));
        } else if (const tinyxml2::XMLText* t = n->ToText()) {
            const std::string text = trim(t->Value());
            if (!text.empty()) h.pod(uint8_t(t->CData() ? 'c' : 't')).str(text);
        } else if (n->ToComment()) {
            h.pod(uint8_t('!')).str(n->Value());
        } else if (n->ToDeclaration()) {
            h.pod(uint8_t('?')).str(n->Value());
        } else {
            h.pod(uint8_t('u')).str(n->Value());  // DOCTYPE and the like
        }
    }
}

}  // namespace

Expected<ChunkFile> readChunkFile(const std::string& path, ChunkCoord coord, std::vector<Diagnostic>& diagnostics) {
    ChunkFile cf;
    cf.path = path;
    cf.coord = coord;
    tinyxml2::XMLDocument doc(true, tinyxml2::PRESERVE_WHITESPACE);
    if (Status s = loadXml(path, doc, "chunk file", ErrorKind::BadInput, &cf.contentHash); !s) return s.error();
    Hasher withoutShadows;
    hashWithoutShadows(&doc, 0, withoutShadows);
    cf.contentWithoutShadowsHash = withoutShadows.value();
    int index = 0;
    for (const tinyxml2::XMLElement* e = doc.RootElement()->FirstChildElement(); e; e = e->NextSiblingElement()) {
        std::string n = e->Name();
        if (n != "model" && n != "terrain") continue;
        ChunkObject o;
        o.kind = n == "model" ? ChunkObject::Kind::Model : ChunkObject::Kind::Terrain;
        o.elementIndex = index++;
        o.line = e->GetLineNum();
        auto skip = [&](int line, const std::string& why) {
            if (o.skipped) return;
            o.skipped = true;
            o.skipReason = why;
            diagnostics.push_back({path, line, why + "; " + n + " skipped (its <shadow> is left as it was)"});
        };
        bool seenTransform = false;
        if (auto again = repeatedChild(e)) skip(again->first, again->second);
        for (const tinyxml2::XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
            std::string cn = c->Name();
            if (cn == "resource") o.resource = trim(c->GetText());
            else if (cn == "uuid") o.uuid = trim(c->GetText());
            else if (cn == "castsShadow" && o.kind == ChunkObject::Kind::Model) {
                if (Status s = parseBool(path, c, o.castsShadow); !s) skip(c->GetLineNum(), s.error().message);
            } else if (cn == "transform" && o.kind == ChunkObject::Kind::Model) {
                seenTransform = true;
                if (auto again = repeatedChild(c)) skip(again->first, again->second);
                // The rows are the placement; anything else in it (a <scale>?) may be part of
                // the engine's, which the bake would not know.
                for (const UnknownName& u : unknownChildren(c, kTransformElements)) skip(u.line, u.message);
                const char* rowNames[4] = {"row0", "row1", "row2", "row3"};
                for (int r = 0; r < 4; ++r) {
                    const tinyxml2::XMLElement* re = c->FirstChildElement(rowNames[r]);
                    if (!re) { skip(c->GetLineNum(), std::string("<transform> has no <") + rowNames[r] + ">"); continue; }
                    const Accepted entries = within(r < 3 ? limits::kMaxLinearEntry : limits::kMaxLocalCoordinate);
                    if (Status s = parseVec3(path, re, o.transform.rows[size_t(r)], entries); !s)
                        skip(re->GetLineNum(), s.error().message);
                }
                if (!o.skipped)
                    if (std::string why = o.transform.singularReason(); !why.empty()) skip(c->GetLineNum(), why);
            }
        }
        if (o.resource.empty()) skip(o.line, "<" + n + "> has no <resource>");
        if (o.kind == ChunkObject::Kind::Model && !seenTransform && !o.skipped) {
            // No transform: identity at the chunk origin (a user would expect that).
        }
        cf.objects.push_back(std::move(o));
    }
    return cf;
}

Expected<Mesh> loadModelResource(const std::string& path, std::vector<Diagnostic>* warnings) {
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    // A group whose alpha the mesh file leaves unknown fails the model, unless a .model
    // override below has settled it.
    auto unknownAlpha = [](const Mesh& m) -> std::optional<Error> {
        for (const PrimitiveGroup& g : m.groups)
            if (g.alphaUnknown) return g.alphaUnknown;
        return std::nullopt;
    };
    if (ext != ".model") {
        Expected<Mesh> mesh = loadMeshFile(path);
        if (mesh)
            if (std::optional<Error> e = unknownAlpha(*mesh)) return *e;
        return mesh;
    }
    tinyxml2::XMLDocument doc;
    if (Status s = loadXml(path, doc, "model resource"); !s) return s.error();
    const tinyxml2::XMLElement* root = doc.RootElement();
    if (auto again = repeatedChild(root, {"primitiveGroup"})) return bad(path, again->first, again->second);
    if (Status s = checkResourceNames(path, unknownChildren(root, kModelResourceElements), warnings); !s) return s.error();
    const tinyxml2::XMLElement* visual = root->FirstChildElement("visual");
    if (!visual || trim(visual->GetText()).empty()) return bad(path, root->GetLineNum(), "<model> has no <visual>");
    std::string meshPath = (fs::path(path).parent_path() / trim(visual->GetText())).string();
    Expected<Mesh> mesh = loadMeshFile(meshPath);
    if (!mesh) return mesh.error();
    for (const tinyxml2::XMLElement* g = root->FirstChildElement("primitiveGroup"); g;
         g = g->NextSiblingElement("primitiveGroup")) {
        if (Status s = checkResourceNames(path, unknownAttributes(g, kPrimitiveGroupAttributes), warnings); !s) return s.error();
        int index = -1;
        if (g->QueryIntAttribute("index", &index) != tinyxml2::XML_SUCCESS || index < 0)
            return bad(path, g->GetLineNum(),
                       std::string("<primitiveGroup> needs index=\"N\" (a whole number, 0 or more); got ") +
                           (g->Attribute("index") ? "index=\"" + std::string(g->Attribute("index")) + "\"" : "no index"));
        if (size_t(index) >= mesh->groups.size())
            return bad(path, g->GetLineNum(), "<primitiveGroup index=\"" + std::to_string(index) + "\"> but " + meshPath +
                                                  " has " + std::to_string(mesh->groups.size()) + " group(s)");
        PrimitiveGroup& pg = mesh->groups[size_t(index)];
        for (auto [attr, flag] : {std::pair<const char*, bool*>{"alphaTest", &pg.alphaTested}, {"doubleSided", &pg.doubleSided}}) {
            const char* t = g->Attribute(attr);
            if (!t) continue;
            std::string v = t;
            if (v == "true" || v == "1") *flag = true;
            else if (v == "false" || v == "0") *flag = false;
            else return bad(path, g->GetLineNum(), std::string(attr) + " expects true or false, got '" + v + "'");
            if (flag == &pg.alphaTested) pg.alphaUnknown.reset();  // the override decides
        }
    }
    if (std::optional<Error> e = unknownAlpha(*mesh)) return *e;
    mesh->sourceFiles.insert(mesh->sourceFiles.begin(), path);
    return mesh;
}

namespace {

// libpng reads from memory: the file was read whole by readRegularFile (which refuses a
// FIFO or directory named like a heightmap instead of blocking on it).
struct PngReader {
    png_structp png = nullptr;
    png_infop info = nullptr;
    const std::string* bytes = nullptr;
    size_t at = 0;
    std::string message;  // libpng's reason, for the error (it prints nothing itself)
    ~PngReader() {
        if (png) png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
    }
    [[noreturn]] static void error(png_structp png, png_const_charp what) {
        static_cast<PngReader*>(png_get_error_ptr(png))->message = what ? what : "";
        png_longjmp(png, 1);
    }
    static void warning(png_structp, png_const_charp) {}  // e.g. an unknown chunk: read on
    static void read(png_structp png, png_bytep out, png_size_t n) {
        auto* r = static_cast<PngReader*>(png_get_io_ptr(png));
        if (n > r->bytes->size() - r->at) png_error(png, "truncated");
        std::memcpy(out, r->bytes->data() + r->at, n);
        r->at += n;
    }
};

}  // namespace

Expected<Heightfield> loadTerrainResource(const std::string& path, double chunkSize, std::vector<Diagnostic>* warnings) {
    tinyxml2::XMLDocument doc;
    if (Status s = loadXml(path, doc, "terrain resource"); !s) return s.error();
    const tinyxml2::XMLElement* root = doc.RootElement();
    if (auto again = repeatedChild(root)) return bad(path, again->first, again->second);
    if (Status s = checkResourceNames(path, unknownChildren(root, kTerrainResourceElements), warnings); !s) return s.error();
    const tinyxml2::XMLElement* he = root->FirstChildElement("heights");
    const tinyxml2::XMLElement* mn = root->FirstChildElement("minHeight");
    const tinyxml2::XMLElement* mx = root->FirstChildElement("maxHeight");
    if (!he || !mn || !mx) return bad(path, root->GetLineNum(), "<terrain> needs <heights>, <minHeight> and <maxHeight>");
    double minH = 0, maxH = 0;
    if (Status s = parseDouble(path, mn, minH, within(limits::kMaxLength)); !s) return s.error();
    if (Status s = parseDouble(path, mx, maxH, within(limits::kMaxLength)); !s) return s.error();
    if (maxH < minH)
        return bad(path, mx->GetLineNum(), "<maxHeight> " + formatExact(maxH) + " is below <minHeight> " + formatExact(minH));
    const std::string png = (fs::path(path).parent_path() / trim(he->GetText())).string();

    Expected<std::string> bytes = readRegularFile(png, "heightmap", ErrorKind::MissingResource, size_t(1) << 30);
    if (!bytes) return bytes.error();
    PngReader r;
    r.bytes = &*bytes;
    if (bytes->size() < 8 || png_sig_cmp(reinterpret_cast<png_const_bytep>(bytes->data()), 0, 8))
        return bad(png, 0, "not a PNG file");
    r.at = 8;
    r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &r, &PngReader::error, &PngReader::warning);
    r.info = r.png ? png_create_info_struct(r.png) : nullptr;
    if (!r.info) return makeError(ErrorKind::Internal, png, 0, "libpng initialisation failed");
    Heightfield hf;
    hf.size = chunkSize;
    hf.sourceFiles = {path, png};
    std::vector<png_byte> data;
    std::vector<png_bytep> rows;
    // libpng reports corrupt or truncated data by longjmp, which skips the destructor of
    // anything constructed after this point: everything with one lives in `hf`, `data`,
    // `rows` and `r`, made before it, which the return after the jump cleans up.
    if (setjmp(png_jmpbuf(r.png))) return bad(png, 0, "corrupt or truncated PNG data (libpng: " + r.message + ")");
    png_set_read_fn(r.png, &r, &PngReader::read);
    png_set_sig_bytes(r.png, 8);
    png_read_info(r.png, r.info);
    png_uint_32 w = png_get_image_width(r.png, r.info), h = png_get_image_height(r.png, r.info);
    int depth = png_get_bit_depth(r.png, r.info), color = png_get_color_type(r.png, r.info);
    if (color != PNG_COLOR_TYPE_GRAY || depth != 16)
        return bad(png, 0, "heightmap must be 16-bit grey (found " + std::to_string(depth) + "-bit, colour type " +
                               std::to_string(color) + "); terrain skipped");
    if (w != h || w < 2)
        return bad(png, 0, "heightmap must be square with N >= 2 samples (found " + std::to_string(w) + " x " +
                               std::to_string(h) + ")");
    if (w > 16385) return bad(png, 0, "heightmap larger than 16385 x 16385");
    hf.n = int(w);
    const size_t rowBytes = png_get_rowbytes(r.png, r.info);
    data.resize(rowBytes * h);
    rows.resize(h);
    for (png_uint_32 j = 0; j < h; ++j) rows[j] = data.data() + j * rowBytes;
    png_read_image(r.png, rows.data());
    hf.heights.resize(size_t(w) * h);
    const double scale = (maxH - minH) / 65535.0;
    for (png_uint_32 j = 0; j < h; ++j)
        for (png_uint_32 i = 0; i < w; ++i) {
            unsigned v = (unsigned(rows[j][2 * i]) << 8) | rows[j][2 * i + 1];  // PNG is big-endian
            hf.heights[size_t(j) * w + i] = minH + double(v) * scale;
        }
    return hf;
}

}  // namespace shadowcull
