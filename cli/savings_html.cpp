// The HTML page of `shadowcull report --html`: self-contained (inline CSS and SVG, no
// script, no network). Per light a top-down map of the chunks coloured by the share of
// their shadow-pass triangles that only the bake removes (of what the engine's own culling
// leaves), the per-light and per-chunk tables, and the biggest single savings with their
// proofs.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "cli/html_text.h"
#include "cli/savings_model.h"
#include "core/scene.h"

namespace shadowcull::cli::savings_detail {

namespace {

using results::LightSavingsRecord;
using results::WorkRecord;

std::string esc(const std::string& s) { return htmlEscape(s); }

std::string num(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f", v);
    return buf;
}

// The colour of a share in [0, 1]: a sequential ramp (ColorBrewer YlGnBu), pale for
// nothing removed, dark blue for everything.
std::string shareColour(double t) {
    static const int stops[5][3] = {{255, 255, 204}, {161, 218, 180}, {65, 182, 196}, {44, 127, 184}, {37, 52, 148}};
    t = std::clamp(t, 0.0, 1.0) * 4.0;
    const int k = std::min(3, int(t));
    const double f = t - k;
    char buf[8];
    int c[3];
    for (int i = 0; i < 3; ++i) c[i] = int(std::lround(stops[k][i] + f * (stops[k + 1][i] - stops[k][i])));
    std::snprintf(buf, sizeof buf, "#%02x%02x%02x", c[0], c[1], c[2]);
    return buf;
}

// A table cell pair: casters, triangles.
std::string cells(const WorkRecord& w) {
    return "<td class=\"n\">" + grouped(w.casters) + "</td><td class=\"n\">" + grouped(w.triangles) + "</td>";
}

std::string savingsCells(const LightSavingsRecord& s) {
    const WorkRecord left = savings::afterEngine(s);
    return cells(s.all) + cells(s.engineCulls) + cells(left) + cells(s.bakeCulls) + "<td class=\"n b\">" +
           percent(s.bakeCulls.triangles, left.triangles) + "</td>" + cells(savings::afterBake(s)) + cells(s.undecided);
}

const char* kTableHead =
    "<tr><th rowspan=\"2\">%s</th><th colspan=\"2\">every caster</th><th colspan=\"2\">(a) engine culls</th>"
    "<th colspan=\"2\">left after (a)</th><th colspan=\"2\">(b) only this bake</th><th rowspan=\"2\">(b) of what (a) "
    "leaves, triangles</th><th colspan=\"2\">left after (b)</th><th colspan=\"2\">undecided (kept, unproved)</th></tr>\n"
    "<tr><th>casters</th><th>triangles</th><th>casters</th><th>triangles</th><th>casters</th><th>triangles</th>"
    "<th>casters</th><th>triangles</th><th>casters</th><th>triangles</th><th>casters</th><th>triangles</th></tr>\n";

std::string tableHead(const char* first) {
    char buf[1024];
    std::snprintf(buf, sizeof buf, kTableHead, first);
    return buf;
}

struct Grid {
    int minX = 0, minZ = 0, nx = 1, nz = 1;
    double cell = 20;  // pixels per chunk
    double margin = 24;
    double width() const { return 2 * margin + nx * cell; }
    double height() const { return 2 * margin + nz * cell; }
};

Grid gridOf(const std::vector<results::ChunkRecord>& chunks) {
    Grid g;
    int maxX = 0, maxZ = 0;
    bool any = false;
    for (const results::ChunkRecord& c : chunks)
        if (std::optional<ChunkCoord> cc = parseChunkName(c.chunk)) {
            if (!any) g.minX = maxX = cc->x, g.minZ = maxZ = cc->z, any = true;
            g.minX = std::min(g.minX, int(cc->x)), maxX = std::max(maxX, int(cc->x));
            g.minZ = std::min(g.minZ, int(cc->z)), maxZ = std::max(maxZ, int(cc->z));
        }
    g.nx = maxX - g.minX + 1, g.nz = maxZ - g.minZ + 1;
    g.cell = std::clamp(280.0 / std::max(g.nx, g.nz), 3.0, 64.0);
    return g;
}

// One light's map: x right, z down the page (seen from above), one square per chunk.
std::string lightMap(const ReportModel& m, const Grid& g, size_t l) {
    const results::LightRecord& L = m.file.lights[l];
    std::ostringstream o;
    o << "<svg class=\"map\" width=\"" << num(g.width()) << "\" height=\"" << num(g.height()) << "\" viewBox=\"0 0 "
      << num(g.width()) << " " << num(g.height()) << "\" xmlns=\"http://www.w3.org/2000/svg\">\n";
    o << "<defs><pattern id=\"none" << l << "\" width=\"6\" height=\"6\" patternUnits=\"userSpaceOnUse\" "
      << "patternTransform=\"rotate(45)\"><rect width=\"6\" height=\"6\" fill=\"#e4e4e4\"/><line x1=\"0\" y1=\"0\" "
      << "x2=\"0\" y2=\"6\" stroke=\"#bdbdbd\" stroke-width=\"2\"/></pattern>"
      << "<clipPath id=\"clip" << l << "\"><rect x=\"" << num(g.margin) << "\" y=\"" << num(g.margin) << "\" width=\""
      << num(g.nx * g.cell) << "\" height=\"" << num(g.nz * g.cell) << "\"/></clipPath></defs>\n";
    o << "<rect class=\"bg\" x=\"" << num(g.margin) << "\" y=\"" << num(g.margin) << "\" width=\"" << num(g.nx * g.cell)
      << "\" height=\"" << num(g.nz * g.cell) << "\"/>\n";
    for (size_t k = 0; k < m.file.chunks.size(); ++k) {
        const results::ChunkRecord& c = m.file.chunks[k];
        const std::optional<ChunkCoord> cc = parseChunkName(c.chunk);
        if (!cc || l >= m.tally.chunks()[k].size()) continue;
        const LightSavingsRecord& s = m.tally.chunks()[k][l];
        const WorkRecord left = savings::afterEngine(s);
        const double x = g.margin + (cc->x - g.minX) * g.cell, y = g.margin + (cc->z - g.minZ) * g.cell;
        const double share = left.triangles ? double(s.bakeCulls.triangles) / double(left.triangles) : 0.0;
        const std::string fill = left.triangles ? shareColour(share) : "url(#none" + std::to_string(l) + ")";
        o << "<rect class=\"chunk\" x=\"" << num(x) << "\" y=\"" << num(y) << "\" width=\"" << num(g.cell) << "\" height=\""
          << num(g.cell) << "\" fill=\"" << fill << "\"><title>" << esc(c.chunk) << " (x " << cc->x << ", z " << cc->z
          << "), light " << L.index << " '" << esc(L.name) << "'\nevery caster: " << grouped(s.all.casters) << " casters, "
          << grouped(s.all.triangles) << " triangles\n(a) engine culls: " << grouped(s.engineCulls.triangles)
          << " triangles\nleft after (a): " << grouped(left.triangles) << " triangles\n(b) only this bake: "
          << grouped(s.bakeCulls.casters) << " casters, " << grouped(s.bakeCulls.triangles) << " triangles ("
          << percent(s.bakeCulls.triangles, left.triangles) << " of what (a) leaves)\nundecided: "
          << grouped(s.undecided.casters) << " casters, " << grouped(s.undecided.triangles) << " triangles</title></rect>\n";
        if (g.cell >= 34 && left.triangles) {
            o << "<text class=\"pct\" x=\"" << num(x + g.cell / 2) << "\" y=\"" << num(y + g.cell / 2 + 4) << "\" fill=\""
              << (share > 0.45 ? "#fff" : "#222") << "\">"
              << (share > 0 && share < 0.005 ? std::string("&lt;1") : std::to_string(std::lround(100 * share))) << "%</text>\n";
        }
    }
    // Where a point or spot light stands, and its range.
    if (L.position) {
        const double px = g.margin + (L.position->x / m.chunkSize - g.minX) * g.cell;
        const double py = g.margin + (L.position->z / m.chunkSize - g.minZ) * g.cell;
        o << "<g clip-path=\"url(#clip" << l << ")\">";
        if (L.range)
            o << "<circle class=\"range\" cx=\"" << num(px) << "\" cy=\"" << num(py) << "\" r=\""
              << num(*L.range / m.chunkSize * g.cell) << "\"/>";
        o << "<circle class=\"lamp\" cx=\"" << num(px) << "\" cy=\"" << num(py) << "\" r=\"4\"><title>light "
          << L.index << " '" << esc(L.name) << "' at x " << num(L.position->x) << ", z " << num(L.position->z)
          << (L.range ? ", range " + num(*L.range) + " m" : "") << "</title></circle></g>\n";
    }
    // Axes: world x to the right, z down the page.
    const double right = g.margin + g.nx * g.cell, bottom = g.margin + g.nz * g.cell;
    o << "<text class=\"ax\" x=\"" << num(right) << "\" y=\"" << num(bottom + 15) << "\" text-anchor=\"end\">x &#8594;</text>"
      << "<text class=\"ax\" x=\"" << num(g.margin - 4) << "\" y=\"" << num(bottom) << "\" text-anchor=\"end\">z</text>"
      << "<text class=\"ax\" x=\"" << num(g.margin - 4) << "\" y=\"" << num(bottom + 12) << "\" text-anchor=\"end\">&#8595;</text>"
      << "<text class=\"ax\" x=\"" << num(g.margin) << "\" y=\"" << num(g.margin - 6) << "\">chunk x " << g.minX << "..."
      << g.minX + g.nx - 1 << ", z " << g.minZ << "..." << g.minZ + g.nz - 1 << "</text>\n";
    o << "</svg>";
    return o.str();
}

std::string legend() {
    std::ostringstream o;
    o << "<svg class=\"legend\" width=\"560\" height=\"46\" viewBox=\"0 0 560 46\" xmlns=\"http://www.w3.org/2000/svg\">"
      << "<defs><linearGradient id=\"ramp\">";
    for (int k = 0; k <= 10; ++k) o << "<stop offset=\"" << k * 10 << "%\" stop-color=\"" << shareColour(k / 10.0) << "\"/>";
    o << "</linearGradient><pattern id=\"nonel\" width=\"6\" height=\"6\" patternUnits=\"userSpaceOnUse\" "
         "patternTransform=\"rotate(45)\"><rect width=\"6\" height=\"6\" fill=\"#e4e4e4\"/><line x1=\"0\" y1=\"0\" x2=\"0\" "
         "y2=\"6\" stroke=\"#bdbdbd\" stroke-width=\"2\"/></pattern></defs>"
      << "<rect x=\"10\" y=\"6\" width=\"300\" height=\"16\" fill=\"url(#ramp)\" stroke=\"#888\"/>";
    for (int k = 0; k <= 4; ++k)
        o << "<line x1=\"" << 10 + k * 75 << "\" y1=\"22\" x2=\"" << 10 + k * 75 << "\" y2=\"27\" stroke=\"#555\"/><text x=\""
          << 10 + k * 75 << "\" y=\"39\" text-anchor=\"middle\">" << k * 25 << "%</text>";
    o << "<rect x=\"340\" y=\"6\" width=\"22\" height=\"16\" fill=\"url(#nonel)\" stroke=\"#888\"/>"
      << "<text x=\"368\" y=\"19\">nothing left after (a)</text>"
      << "<circle class=\"lamp\" cx=\"351\" cy=\"35\" r=\"4\"/><text x=\"368\" y=\"39\">point/spot light, dashed: range</text>"
      << "</svg>";
    return o.str();
}

std::string page(const ReportModel& m) {
    const results::ResultsFile& f = m.file;
    std::ostringstream o;
    o << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>shadowcull report</title>\n<style>\n"
         "body{font:14px/1.4 sans-serif;margin:1.5em;color:#222}\n"
         "table{border-collapse:collapse;margin:.5em 0 1.5em}\n"
         "th,td{border:1px solid #bbb;padding:3px 7px;text-align:left;vertical-align:top}\n"
         "th{background:#eee;font-weight:600} td.n{text-align:right;white-space:nowrap} td.b{font-weight:bold}\n"
         "code{font-size:12px} .maps{display:flex;flex-wrap:wrap;gap:1.2em} figure{margin:0}\n"
         "figcaption{font-size:13px;max-width:330px} svg{font:11px sans-serif}\n"
         "rect.bg{fill:#fafafa;stroke:#999} rect.chunk{stroke:#fff;stroke-width:.5} rect.chunk:hover{stroke:#d62728;stroke-width:2}\n"
         "text.pct{text-anchor:middle;font-size:11px;pointer-events:none} text.ax{fill:#555}\n"
         "circle.lamp{fill:#ff8c00;stroke:#222;stroke-width:1} circle.range{fill:none;stroke:#ff8c00;stroke-width:1.5;"
         "stroke-dasharray:4 3}\n"
         ".note{max-width:60em;color:#444} details{margin:.3em 0} summary{cursor:pointer}\n"
         "</style></head><body>\n<h1>shadowcull report</h1>\n";
    uint64_t groups = 0, tris = 0;
    for (const results::ChunkRecord& c : f.chunks)
        for (const results::ObjectRecord& ob : c.objects)
            for (const results::GroupRecord& g : ob.groups) ++groups, tris += g.triangles.value_or(0);
    o << "<p>space <code>" << esc(m.spaceDir) << "</code>, results <code>" << esc(m.resultsPath) << "</code>: "
      << f.chunks.size() << " chunks, " << f.lights.size() << " lights, " << grouped(groups) << " caster groups, "
      << grouped(tris) << " placed triangles.</p>\n";
    o << "<p class=\"note\">Each light's shadow pass draws casters (primitive groups) and their placed triangles. "
         "<b>(a)</b> is what the engine's own run-time culling already removes: casters with <code>castsShadow</code> "
         "false, and casters beyond a point or spot light's range or outside a spot's cone. <b>(b)</b> is what only this "
         "bake removes: casters proved hidden or proved to cast onto nothing; it is read against what (a) leaves. "
         "<b>Undecided</b> casters are kept (bit 1) without a proof: the savings still left on the table.</p>\n";

    o << "<h2>Per light, the whole world</h2>\n<table>\n" << tableHead("light");
    for (size_t l = 0; l < f.lights.size() && l < m.tally.world().size(); ++l)
        o << "<tr class=\"light\"><td>" << esc(lightLabel(f.lights[l])) << "</td>" << savingsCells(m.tally.world()[l]) << "</tr>\n";
    o << "</table>\n";

    o << "<h2>Maps: the share of each chunk's shadow-pass triangles that only the bake removes</h2>\n"
      << "<p class=\"note\">Seen from above, world x to the right, z down the page; one square per chunk, coloured by "
         "(b) / (what (a) leaves), in triangles. Hover over a chunk for its name and figures.</p>\n"
      << legend() << "\n<div class=\"maps\">\n";
    const Grid g = gridOf(f.chunks);
    for (size_t l = 0; l < f.lights.size() && l < m.tally.world().size(); ++l) {
        const LightSavingsRecord& s = m.tally.world()[l];
        const WorkRecord left = savings::afterEngine(s);
        o << "<figure>" << lightMap(m, g, l) << "<figcaption><b>" << esc(lightLabel(f.lights[l])) << "</b>: (b) removes "
          << grouped(s.bakeCulls.triangles) << " of the " << grouped(left.triangles) << " triangles (a) leaves ("
          << percent(s.bakeCulls.triangles, left.triangles) << "); (a) removes " << grouped(s.engineCulls.triangles)
          << " of " << grouped(s.all.triangles) << ".</figcaption></figure>\n";
    }
    o << "</div>\n";

    o << "<h2>Biggest single savings beyond the engine's culling</h2>\n";
    if (m.biggest.empty()) o << "<p>None: the bake removed nothing beyond what the engine culls itself.</p>\n";
    else {
        o << "<table><tr><th>#</th><th>triangles</th><th>groups</th><th>chunk</th><th>object</th><th>light</th>"
             "<th>proof, per group (as <code>shadowcull explain</code> prints it)</th></tr>\n";
        for (size_t k = 0; k < m.biggest.size(); ++k) {
            const BigSaving& b = m.biggest[k];
            const results::ChunkRecord& c = f.chunks[b.chunk];
            const results::ObjectRecord& ob = c.objects[b.object];
            o << "<tr class=\"big\"><td class=\"n\">" << k + 1 << "</td><td class=\"n\">" << grouped(b.removed.triangles)
              << "</td><td class=\"n\">" << b.removed.casters << "</td><td>" << esc(c.chunk) << "</td><td>"
              << esc(objectLabel(ob)) << "</td><td>" << esc(lightLabel(f.lights[size_t(b.light - 1)])) << "</td><td>";
            bool first = true;
            for (const results::GroupRecord& gr : ob.groups) {
                const results::BitRecord& bit = gr.lights[size_t(b.light - 1)];
                if (savings::classify(bit.verdict, bit.stage, bit.reason) != savings::Why::BakeCulls) continue;
                o << (first ? "" : "<br>") << "group " << gr.group << " (" << grouped(gr.triangles.value_or(0))
                  << " triangles): " << esc(proofText(bit));
                first = false;
            }
            o << "</td></tr>\n";
        }
        o << "</table>\n";
    }

    o << "<h2>Per chunk</h2>\n";
    for (size_t l = 0; l < f.lights.size() && l < m.tally.world().size(); ++l) {
        o << "<details><summary>" << esc(lightLabel(f.lights[l])) << "</summary>\n<table>\n" << tableHead("chunk");
        for (size_t k = 0; k < f.chunks.size(); ++k)
            o << "<tr><td>" << esc(f.chunks[k].chunk) << "</td>" << savingsCells(m.tally.chunks()[k][l]) << "</tr>\n";
        o << "</table></details>\n";
    }
    o << "</body></html>\n";
    return o.str();
}

}  // namespace

std::string htmlReport(const ReportModel& m) { return page(m); }

}  // namespace shadowcull::cli::savings_detail
