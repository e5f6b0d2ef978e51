#include <cmath>
#include <cstdio>
#include <sstream>
#include <tuple>

#include <nlohmann/json.hpp>

#include "cli/diff_model.h"

namespace shadowcull::cli::diff_detail {

using nlohmann::json;

std::string lightText(const LightInfo& L) { return "'" + L.name + "' (" + L.type + ")"; }

std::string lightParameterChanges(const LightInfo& a, const LightInfo& b) {
    std::string s;
    auto add = [&](const std::string& part) { s += (s.empty() ? "" : ", ") + part; };
    // A side that does not record a parameter (an older results file) says nothing of it.
    for (const auto& [what, x, y] : {std::tuple{"position", &a.position, &b.position},
                                     std::tuple{"direction", &a.direction, &b.direction}})
        if (*x && *y && **x != **y) add(std::string(what) + " " + vecText(**x) + " -> " + vecText(**y));
    for (const auto& [what, x, y, unit] :
         {std::tuple{"range", &a.range, &b.range, " m"}, std::tuple{"cone", &a.coneAngle, &b.coneAngle, " deg"},
          std::tuple{"bias", &a.bias, &b.bias, " m"}, std::tuple{"slope bias", &a.slopeBias, &b.slopeBias, " m"},
          std::tuple{"filter radius", &a.filterRadius, &b.filterRadius, " m"},
          std::tuple{"normal bias", &a.normalBias, &b.normalBias, " m"}})
        if (*x && *y && **x != **y) add(std::string(what) + " " + num(**x) + " -> " + num(**y) + unit);
    return s;
}

std::string num(double v) {
    if (v == 0) v = 0;  // no "-0"
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

std::string vecText(const Vec& v) { return "(" + num(v[0]) + ", " + num(v[1]) + ", " + num(v[2]) + ")"; }

// Depth of q behind p along the (normalised) ray.
double depthGap(const WitnessRay& w) {
    const double len =
        std::sqrt(w.direction[0] * w.direction[0] + w.direction[1] * w.direction[1] + w.direction[2] * w.direction[2]);
    double d = 0;
    for (int k = 0; k < 3; ++k) d += (w.q[size_t(k)] - w.p[size_t(k)]) * w.direction[size_t(k)];
    return len > 0 ? d / len : 0.0;
}

std::string evidenceText(const Evidence& e) {
    if (e.verdict.empty()) return "bit " + std::to_string(e.bit) + " (mask only, no evidence)";
    if (e.verdict == "undecided") return "undecided, kept as 1";
    std::string s = e.verdict + " by " + (e.stage.empty() ? "?" : e.stage);
    if (e.witness)
        return s + ": witness ray p " + vecText(e.witness->p) + " -> q " + vecText(e.witness->q) + " on " +
               e.witness->receiver + ", gap " + num(depthGap(*e.witness)) + " m";
    return e.reason.empty() || e.reason == "witness ray" ? s : s + ": " + e.reason;
}

std::string verdictShort(const Evidence& e) {
    if (e.verdict.empty()) return "?";
    return e.verdict + (e.stage.empty() ? "" : "/" + e.stage);
}

std::string lightLabel(const Comparison& c, int light) {
    std::string s = "light " + std::to_string(light);
    if (size_t(light) <= c.lights.size()) {
        const LightRow& r = c.lights[size_t(light - 1)];
        const std::optional<LightInfo>& L = r.after ? r.after : r.before;
        if (L) s += " '" + L->name + "'";
    }
    return s;
}

std::string sideText(const Bake& b) {
    return b.path + " (" + (b.results ? "results JSON" : "baked space, masks only") + ", " +
           std::to_string(b.chunks.size()) + (b.chunks.size() == 1 ? " chunk)" : " chunks)");
}

namespace {

std::string pad(const std::string& s, size_t w, bool right = true) {
    if (s.size() >= w) return s;
    return right ? std::string(w - s.size(), ' ') + s : s + std::string(w - s.size(), ' ');
}

}  // namespace

std::string textReport(const Bake& a, const Bake& b, const Comparison& c) {
    std::ostringstream o;
    o << "shadowcull diff\n  old: " << sideText(a) << "\n  new: " << sideText(b) << "\n";
    for (const std::string& n : c.notes) o << "note: " << n << "\n";
    o << "\n";
    if (c.lightsDiffer) {
        o << "*** LIGHT LISTS DIFFER: bits are compared by light index ***\n";
        for (const LightRow& r : c.lights) {
            if (r.change.empty()) continue;
            o << "  light " << r.index << ": " << (r.before ? lightText(*r.before) : "-") << " -> "
              << (r.after ? lightText(*r.after) : "-") << ": " << r.change << "\n";
        }
        for (const std::string& m : c.lightMoves) o << "  " << m << " (its bits now compare against another light's)\n";
    } else if (c.lightsKnown) {
        o << "lights:";
        for (const LightRow& r : c.lights)
            o << (r.index > 1 ? "," : "") << " " << r.index << " " << lightText(*r.after);
        if (c.lights.empty()) o << " none";
        o << "\n";
        for (const LightRow& r : c.lights)
            if (!r.change.empty()) o << "  light " << r.index << " " << lightText(*r.after) << ": " << r.change << "\n";
    } else {
        o << "lights: " << c.lightCount << " compared by index (names unknown)\n";
    }

    o << "\n"
      << pad("chunk", 16, false) << pad("bits", 8) << pad("changed", 9) << pad("1->0", 7) << pad("0->1", 7)
      << pad("verdict-only", 14) << "  objects +added -removed ~changed\n";
    auto line = [&](const ChunkRow& r) {
        o << pad(r.chunk, 16, false) << pad(std::to_string(r.bits), 8) << pad(std::to_string(r.changed), 9)
          << pad(std::to_string(r.toZero), 7) << pad(std::to_string(r.toOne), 7)
          << pad(std::to_string(r.verdictOnly), 14) << "  +" << r.added << " -" << r.removed << " ~" << r.otherObject
          << (r.status.empty() ? "" : "  (" + r.status + ")") << "\n";
    };
    for (const ChunkRow& r : c.chunks) line(r);
    line(c.total);

    auto rows = [&](const std::vector<BitRow>& list) {
        for (const BitRow& r : list) {
            o << "  " << r.object.chunk << "  " << r.object.label() << "  group " << r.group << "  "
              << lightLabel(c, r.light) << ": ";
            if (r.bitChanged)
                o << r.before.bit << " -> " << r.after.bit << "\n";
            else
                o << "bit " << r.after.bit << ", " << verdictShort(r.before) << " -> " << verdictShort(r.after) << "\n";
            o << "      old: " << evidenceText(r.before) << "\n      new: " << evidenceText(r.after)
              << "\n      evidence: ";
            for (size_t k = 0; k < r.notes.size(); ++k) o << (k ? ", " : "") << r.notes[k];
            o << "\n";
        }
    };
    o << "\nchanged bits (" << c.changed.size()
      << "), by chunk, object, group, light:" << (c.changed.empty() ? " none" : "") << "\n";
    rows(c.changed);
    o << "\nverdict-only changes, bit unchanged (" << c.verdictOnly.size()
      << "):" << (c.verdictOnly.empty() ? " none" : "") << "\n";
    rows(c.verdictOnly);
    o << "\nobject changes (" << c.objects.size() << "):" << (c.objects.empty() ? " none" : "") << "\n";
    for (const ObjectRow& r : c.objects)
        o << "  " << r.object.chunk << (r.object.kind == "chunk" ? "" : "  " + r.object.label()) << ": " << r.change
          << "\n";
    bool simHeader = false;
    for (const ChunkRow& r : c.chunks) {
        if (r.simRemoved.empty() && r.simAdded.empty()) continue;
        if (!simHeader) o << "\nsimulated effects changed (informational):\n";
        simHeader = true;
        o << "  " << r.chunk << "\n";
        for (const std::string& s : r.simRemoved) o << "    - " << s << "\n";
        for (const std::string& s : r.simAdded) o << "    + " << s << "\n";
    }
    if (a.warnings || b.warnings) o << "\nwarnings in the bakes: old " << a.warnings << ", new " << b.warnings << "\n";

    o << "\nresult: ";
    if (!c.anyChange()) {
        o << "no changes\n";
    } else {
        o << c.changed.size() << " bits changed (" << c.total.toZero << " 1->0, " << c.total.toOne << " 0->1), "
          << c.verdictOnly.size() << " verdict-only changes, " << c.objects.size() << " object changes"
          << (c.lightsDiffer ? ", LIGHT LISTS DIFFER" : "") << (c.lightsEdited ? ", light settings changed" : "")
          << "\n";
    }
    return o.str();
}

// --- JSON ---

namespace {

json vecJson(const Vec& v) { return json::array({v[0], v[1], v[2]}); }

json evidenceJson(const Evidence& e) {
    json j = {{"bit", e.bit}};
    if (!e.verdict.empty()) j["verdict"] = e.verdict;
    if (!e.stage.empty()) j["stage"] = e.stage;
    if (!e.reason.empty()) j["reason"] = e.reason;
    if (e.witness)
        j["witness"] = {{"origin", vecJson(e.witness->origin)},
                        {"direction", vecJson(e.witness->direction)},
                        {"p", vecJson(e.witness->p)},
                        {"q", vecJson(e.witness->q)},
                        {"receiver", e.witness->receiver}};
    return j;
}

json objectJson(const ObjectRef& r) {
    json j = {{"chunk", r.chunk}, {"kind", r.kind}, {"element", r.element}};
    if (!r.uuid.empty()) j["uuid"] = r.uuid;
    return j;
}

json sideJson(const Bake& b) {
    json lights = json::array();
    for (size_t i = 0; i < b.lights.size(); ++i)
        lights.push_back({{"index", i + 1}, {"name", b.lights[i].name}, {"type", b.lights[i].type}});
    json j = {{"path", b.path},
              {"source", b.results ? "results" : "space"},
              {"evidence", b.results},
              {"chunks", b.chunks.size()},
              {"warnings", b.warnings}};
    if (b.lightsKnown) j["lights"] = lights;
    return j;
}

json countsJson(const ChunkRow& r) {
    return {{"bits", r.bits},
            {"changed", r.changed},
            {"toZero", r.toZero},
            {"toOne", r.toOne},
            {"verdictOnly", r.verdictOnly},
            {"objectsAdded", r.added},
            {"objectsRemoved", r.removed},
            {"objectsChanged", r.otherObject}};
}

}  // namespace

std::string jsonReport(const Bake& a, const Bake& b, const Comparison& c) {
    json j;
    j["format"] = "shadowcull-diff";
    j["version"] = 1;
    j["old"] = sideJson(a);
    j["new"] = sideJson(b);
    j["notes"] = c.notes;
    j["changed"] = c.anyChange();
    j["lightsDiffer"] = c.lightsDiffer;
    j["lightsEdited"] = c.lightsEdited;
    json lights = json::array();
    for (const LightRow& r : c.lights) {
        if (r.change.empty()) continue;
        json jl = {{"index", r.index}, {"change", r.change}};
        if (r.before) jl["old"] = {{"name", r.before->name}, {"type", r.before->type}};
        if (r.after) jl["new"] = {{"name", r.after->name}, {"type", r.after->type}};
        lights.push_back(jl);
    }
    j["lightChanges"] = lights;
    j["lightMoves"] = c.lightMoves;
    json chunks = json::array();
    for (const ChunkRow& r : c.chunks) {
        json jc = countsJson(r);
        jc["chunk"] = r.chunk;
        if (!r.status.empty()) jc["status"] = r.status;
        if (!r.simRemoved.empty() || !r.simAdded.empty())
            jc["simulated"] = {{"removed", r.simRemoved}, {"added", r.simAdded}};
        chunks.push_back(jc);
    }
    j["chunks"] = chunks;
    j["totals"] = countsJson(c.total);
    auto bitRows = [&](const std::vector<BitRow>& list) {
        json out = json::array();
        for (const BitRow& r : list) {
            json jr = objectJson(r.object);
            jr["group"] = r.group;
            jr["light"] = r.light;
            jr["old"] = evidenceJson(r.before);
            jr["new"] = evidenceJson(r.after);
            jr["evidence"] = r.notes;
            out.push_back(jr);
        }
        return out;
    };
    j["changedBits"] = bitRows(c.changed);
    j["verdictChanges"] = bitRows(c.verdictOnly);
    json objects = json::array();
    for (const ObjectRow& r : c.objects) {
        json jo = r.object.kind == "chunk" ? json{{"chunk", r.object.chunk}} : objectJson(r.object);
        jo["change"] = r.change;
        objects.push_back(jo);
    }
    j["objectChanges"] = objects;
    return j.dump(1, ' ', false, json::error_handler_t::replace) + "\n";  // paths need not be UTF-8
}

}  // namespace shadowcull::cli::diff_detail
