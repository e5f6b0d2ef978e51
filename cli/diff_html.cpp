#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "cli/diff_model.h"
#include "cli/html_text.h"

namespace shadowcull::cli::diff_detail {

namespace {

std::string esc(const std::string& s) { return htmlEscape(s); }

// What happened to a chunk, in a word or two (the counts say how much).
std::string chunkStatus(const ChunkRow& r) {
    if (!r.status.empty()) return r.status;
    std::string s;
    auto add = [&](const char* what) { s += (s.empty() ? "" : ", ") + std::string(what); };
    if (r.changed) add("bits changed");
    if (r.verdictOnly) add("verdicts changed");
    if (r.added || r.removed || r.otherObject) add("objects changed");
    if (!r.simRemoved.empty() || !r.simAdded.empty()) add("simulated effects changed");
    return s.empty() ? "unchanged" : s;
}

}  // namespace

std::string htmlReport(const Bake& a, const Bake& b, const Comparison& c) {
    std::ostringstream o;
    o << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>shadowcull diff</title>\n<style>\n"
         "body{font:14px/1.4 sans-serif;margin:1.5em;color:#222}\n"
         "table{border-collapse:collapse;margin:.5em 0 1.5em}\n"
         "th,td{border:1px solid #bbb;padding:3px 7px;text-align:left;vertical-align:top}\n"
         "th{background:#eee} td.n{text-align:right} td.b{white-space:nowrap} code{font-size:12px}\n"
         ".warn{background:#fdd;border:2px solid #c00;padding:.5em 1em;font-weight:bold}\n"
         ".note{background:#ffd;padding:.3em 1em}\n"
         ".group{display:flex;gap:1em;align-items:flex-start;margin-bottom:1.5em}\n"
         "svg.pic{background:#fafafa;font:11px sans-serif;flex:none} .frame{fill:none;stroke:#999}\n"
         "line.old{stroke:#1f77b4;stroke-width:2} line.new{stroke:#d62728;stroke-width:2}\n"
         "line.path{stroke-width:1;stroke-dasharray:3 3;opacity:.7}\n"
         "rect.caster{fill:#777;fill-opacity:.45;stroke:#333;stroke-width:1.2}\n"
         "rect.recv{fill-opacity:.06;stroke-dasharray:5 3;stroke-width:1.2} rect.recv.old{fill:#1f77b4;stroke:#1f77b4}"
         " rect.recv.new{fill:#d62728;stroke:#d62728}\n"
         ".light{stroke:#e08000;stroke-width:2.5;fill:#e08000} .lightdot{fill:#e08000} text.light{stroke:none}\n"
         ".scale{fill:none;stroke:#222;stroke-width:1.5} .lbl{fill:#333} .ttl{font-weight:bold}\n"
         ".caption{max-width:44em;font-size:13px;color:#444}\n"
         "circle.old.p{fill:#1f77b4} circle.new.p{fill:#d62728}\n"
         "circle.old.q{fill:#fff;stroke:#1f77b4;stroke-width:2} circle.new.q{fill:#fff;stroke:#d62728;stroke-width:2}\n"
         ".old{color:#1f77b4} .new{color:#d62728}\n"
         "</style></head><body>\n<h1>shadowcull diff</h1>\n";
    o << "<p>old: <code>" << esc(sideText(a)) << "</code><br>new: <code>" << esc(sideText(b)) << "</code></p>\n";
    for (const std::string& n : c.notes) o << "<p class=\"note\">" << esc(n) << "</p>\n";
    o << "<p><b>result:</b> " << (c.anyChange() ? "changed" : "no changes") << " &mdash; " << c.changed.size()
      << " bits changed, " << c.verdictOnly.size() << " verdict-only changes, " << c.objects.size()
      << " object changes</p>\n";

    o << "<h2>Lights</h2>\n";
    if (c.lightsDiffer) {
        o << "<p class=\"warn\">Light lists differ: bits are compared by light index.";
        for (const std::string& m : c.lightMoves) o << "<br>" << esc(m);
        o << "</p>\n";
    }
    if (c.lightsKnown) {
        o << "<table><tr><th>light</th><th>old</th><th>new</th><th>change</th></tr>\n";
        for (const LightRow& r : c.lights)
            o << "<tr><td class=\"n\">" << r.index << "</td><td>" << (r.before ? esc(lightText(*r.before)) : "-")
              << "</td><td>" << (r.after ? esc(lightText(*r.after)) : "-") << "</td><td>"
              << (r.change.empty() ? "unchanged" : esc(r.change)) << "</td></tr>\n";
        o << "</table>\n";
    } else {
        o << "<p>" << c.lightCount << " lights compared by index (names unknown).</p>\n";
    }

    o << "<h2>Counts per "
         "chunk</h2>\n<table><tr><th>chunk</th><th>bits</th><th>bits changed</th><th>1&rarr;0</th><th>0&rarr;1</th>"
         "<th>verdict-only</th><th>objects added</th><th>objects removed</th><th>objects changed</th><th>status</th></tr>\n";
    auto countRow = [&](const ChunkRow& r) {
        o << "<tr><td>" << esc(r.chunk) << "</td>";
        for (uint64_t v : {r.bits, r.changed, r.toZero, r.toOne, r.verdictOnly, r.added, r.removed, r.otherObject})
            o << "<td class=\"n\">" << v << "</td>";
        o << "<td>" << esc(&r == &c.total ? (c.anyChange() ? "changed" : "unchanged") : chunkStatus(r)) << "</td></tr>\n";
    };
    for (const ChunkRow& r : c.chunks) countRow(r);
    countRow(c.total);
    o << "</table>\n";

    auto bitTable = [&](const std::vector<BitRow>& list) {
        if (list.empty()) return void(o << "<p>none</p>\n");
        o << "<table><tr><th>chunk</th><th>object</th><th>group</th><th>light</th><th>bit</th><th>old</th><th>new</th>"
             "<th>evidence</th></tr>\n";
        for (const BitRow& r : list) {
            o << "<tr><td>" << esc(r.object.chunk) << "</td><td>" << esc(r.object.label()) << "</td><td class=\"n\">"
              << r.group << "</td><td>" << esc(lightLabel(c, r.light)) << "</td><td class=\"b\">" << r.before.bit << " &rarr; "
              << r.after.bit << "</td><td class=\"old\">" << esc(evidenceText(r.before)) << "</td><td class=\"new\">"
              << esc(evidenceText(r.after)) << "</td><td>";
            for (size_t k = 0; k < r.notes.size(); ++k) o << (k ? ", " : "") << esc(r.notes[k]);
            o << "</td></tr>\n";
        }
        o << "</table>\n";
    };
    o << "<h2>Changed bits</h2>\n";
    bitTable(c.changed);
    o << "<h2>Verdict-only changes (bit unchanged)</h2>\n";
    bitTable(c.verdictOnly);

    o << "<h2>Object changes</h2>\n";
    if (c.objects.empty())
        o << "<p>none</p>\n";
    else {
        o << "<table><tr><th>chunk</th><th>object</th><th>change</th></tr>\n";
        for (const ObjectRow& r : c.objects)
            o << "<tr><td>" << esc(r.object.chunk) << "</td><td>"
              << (r.object.kind == "chunk" ? "" : esc(r.object.label())) << "</td><td>" << esc(r.change)
              << "</td></tr>\n";
        o << "</table>\n";
    }

    bool simHeader = false;
    for (const ChunkRow& r : c.chunks) {
        if (r.simRemoved.empty() && r.simAdded.empty()) continue;
        if (!simHeader)
            o << "<h2>Simulated effects changed</h2>\n<table><tr><th>chunk</th><th>old only</th><th>new "
                 "only</th></tr>\n";
        simHeader = true;
        o << "<tr><td>" << esc(r.chunk) << "</td><td class=\"old\">";
        for (const std::string& s : r.simRemoved) o << esc(s) << "<br>";
        o << "</td><td class=\"new\">";
        for (const std::string& s : r.simAdded) o << esc(s) << "<br>";
        o << "</td></tr>\n";
    }
    if (simHeader) o << "</table>\n";

    o << "<h2>Changed groups</h2>\n<p class=\"caption\">Each group from above (x to the right, z down the page) and "
         "from the side (across the light's horizontal direction, y up), both at one scale (scale bar, bottom left). "
         "Grey: the group's box. Dashed: the box of the object a witness ray lands on. Lines: the witness rays, dotted "
         "from the light to p (filled dot, where the ray leaves the group), solid from p to q (hollow dot, where it "
         "lands). Orange arrow: the way the light travels. <span class=\"old\">Blue: old</span>, "
         "<span class=\"new\">red: new</span>.</p>\n";
    if (c.groups.empty()) o << "<p>none</p>\n";
    int pictureId = 0;
    for (const GroupChange& g : c.groups) {
        std::string caption;
        const std::string svg = groupPicture(g, c, a, b, pictureId++, caption);
        o << "<div class=\"group\">" << svg << "<div><h3>" << esc(g.object.chunk) << " "
          << esc(g.object.label()) << " group " << g.group << "</h3><ul>";
        for (const BitRow& r : g.rows)
            o << "<li>" << esc(lightLabel(c, r.light)) << ": " << r.before.bit << " &rarr; " << r.after.bit << " ("
              << esc(verdictShort(r.before)) << " &rarr; " << esc(verdictShort(r.after)) << ")</li>";
        o << "</ul><p class=\"caption\">" << esc(caption) << "</p></div></div>\n";
    }
    o << "</body></html>\n";
    return o.str();
}

}  // namespace shadowcull::cli::diff_detail
