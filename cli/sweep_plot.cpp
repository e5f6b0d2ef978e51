#include "cli/sweep_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace shadowcull::cli {

namespace {

// Widths are estimated, as an SVG writer cannot measure text: monospace glyphs are 0.6 em
// wide; for sans-serif 0.6 em is above the average of lower-case text, so boxes err large.
constexpr double kCharEm = 0.6, kAscent = 0.8, kDescent = 0.25;

struct Box {
    double x0, y0, x1, y1;
    bool overlaps(const Box& o, double gap = 1) const {
        return x0 < o.x1 + gap && o.x0 < x1 + gap && y0 < o.y1 + gap && o.y0 < y1 + gap;
    }
    bool inside(const Box& o) const { return x0 >= o.x0 && y0 >= o.y0 && x1 <= o.x1 && y1 <= o.y1; }
};

std::string fmt(double v, const char* f = "%g") {
    char buf[32];
    std::snprintf(buf, sizeof buf, f, v);
    return buf;
}

std::string esc(const std::string& s) {
    std::string o;
    for (char c : s) o += c == '&' ? "&amp;" : c == '<' ? "&lt;" : c == '>' ? "&gt;" : std::string(1, c);
    return o;
}

// A text element and the box it covers. anchor: "start", "middle" or "end".
struct Text {
    double x, y, size;
    std::string text, anchor = "start";
    bool mono = false, bold = false;
    std::string fill = "#222";
    Box box() const {
        const double w = double(text.size()) * kCharEm * size;
        const double x0 = anchor == "start" ? x : anchor == "middle" ? x - w / 2 : x - w;
        return {x0, y - kAscent * size, x0 + w, y + kDescent * size};
    }
    std::string svg() const {
        return "<text x=\"" + fmt(x, "%.1f") + "\" y=\"" + fmt(y, "%.1f") + "\" font-size=\"" + fmt(size) +
               "\" text-anchor=\"" + anchor + "\"" + (mono ? " font-family=\"monospace\"" : "") +
               (bold ? " font-weight=\"bold\"" : "") + " fill=\"" + fill + "\">" + esc(text) + "</text>\n";
    }
};

double niceStep(double rough) {
    const double p = std::pow(10.0, std::floor(std::log10(rough)));
    for (double m : {1.0, 2.0, 5.0})
        if (m * p >= rough) return m * p;
    return 10 * p;
}

// Places number labels beside their markers: the first candidate position (right, left,
// above, below, the diagonals; then twice and three times as far, with a leader line) that
// stays inside `area` and clear of every marker and label placed so far.
class LabelPlacer {
public:
    explicit LabelPlacer(Box area) : area_(area) {}
    void addObstacle(const Box& b) { taken_.push_back(b); }
    // Returns the label and, when it had to move away, the leader line's far end.
    Text place(double mx, double my, const std::string& text, double size, bool& leader) {
        const double w = double(text.size()) * kCharEm * size, h = (kAscent + kDescent) * size;
        leader = false;
        for (double d : {8.0, 16.0, 26.0, 38.0}) {
            const double c[8][2] = {{d, h / 2 - kDescent * size}, {-d - w, h / 2 - kDescent * size},
                                    {-w / 2, -d},                 {-w / 2, d + h - kDescent * size},
                                    {d * 0.7, -d * 0.7},          {d * 0.7, d * 0.7 + h},
                                    {-d * 0.7 - w, -d * 0.7},     {-d * 0.7 - w, d * 0.7 + h}};
            for (const auto& o : c) {
                Text t{mx + o[0], my + o[1], size, text, "start", true};
                const Box b = t.box();
                if (!b.inside(area_)) continue;
                if (std::any_of(taken_.begin(), taken_.end(), [&](const Box& k) { return k.overlaps(b); })) continue;
                taken_.push_back(b);
                leader = d > 8;
                return t;
            }
        }
        // Crowded: the nearest free place on widening rings around the marker, with a
        // leader line back to it.
        for (double d = 50; d < 2000; d += 12)
            for (int k = 0; k < 32; ++k) {
                const double a = k * 3.14159265358979 / 16;
                Text t{mx + d * std::cos(a) - w / 2, my + d * std::sin(a) + h / 2 - kDescent * size, size, text, "start", true};
                const Box b = t.box();
                if (!b.inside(area_)) continue;
                if (std::any_of(taken_.begin(), taken_.end(), [&](const Box& o) { return o.overlaps(b); })) continue;
                taken_.push_back(b);
                leader = true;
                return t;
            }
        // No room at all (more points than the plot holds labels): the key table still
        // lists the point; its label is left out rather than drawn over another.
        return Text{mx, my, 0, "", "start", true};
    }

private:
    Box area_;
    std::vector<Box> taken_;
};

}  // namespace

std::vector<double> niceLinearTicks(double max) {
    max = std::max(max, 1.0);
    const double step = std::max(1.0, niceStep(max / 4));
    std::vector<double> t;
    for (double v = 0; v < max + step * 0.999; v += step) t.push_back(v);
    return t;
}

std::vector<double> niceLogTicks(double lo, double hi) {
    std::vector<double> t;
    const int e0 = int(std::floor(std::log10(lo))), e1 = int(std::ceil(std::log10(hi)));
    const bool many = e1 - e0 > 4;
    for (int e = e0; e <= e1; ++e)
        for (double m : many ? std::vector<double>{1} : std::vector<double>{1, 2, 5}) {
            const double v = m * std::pow(10.0, e);
            if (v >= lo * 0.999 && v <= hi * 1.001) t.push_back(v);
        }
    return t;
}

std::string sweepSvg(const std::vector<SweepRow>& rows) {
    const double fs = 12, small = 11;
    double tMin = 1e300, tMax = 0;
    uint64_t keepMax = 0, cullMax = 0;
    size_t nameMax = 7;
    for (const SweepRow& r : rows) {
        tMin = std::min(tMin, std::max(r.seconds, 1e-3));
        tMax = std::max(tMax, std::max(r.seconds, 1e-3));
        keepMax = std::max(keepMax, r.falseKeeps);
        cullMax = std::max(cullMax, r.falseCulls);
        nameMax = std::max(nameMax, r.setting.size());
    }
    if (rows.empty()) tMin = 0.1, tMax = 1;
    // The x range: padded, and at least a factor 10 wide so that ticks exist.
    double lo = tMin / 1.4, hi = tMax * 1.4;
    if (hi / lo < 10) {
        const double mid = std::sqrt(lo * hi);
        lo = mid / std::sqrt(10.0), hi = mid * std::sqrt(10.0);
    }
    const std::vector<double> xt = niceLogTicks(lo, hi), kt = niceLinearTicks(double(keepMax)),
                              ct = niceLinearTicks(double(cullMax));

    // Key table columns (monospace): number, setting, seconds, false keeps, false culls.
    const double cw = kCharEm * small;
    const double colNum = 0, colName = 4 * cw, colSec = colName + double(nameMax + 2) * cw;
    const double colKeep = colSec + 10 * cw, colCull = colKeep + 13 * cw, keyW = colCull + 12 * cw;
    const double left = 80, right = 30;
    const double W = std::max(860.0, left + keyW + right);
    const double plotL = left, plotR = W - right - 10;
    const double mainT = 78, mainB = mainT + 280, cullT = mainB + 34, cullB = cullT + 80;
    const double xTitleY = cullB + 40, keyT = xTitleY + 30, rowH = small + 5;
    const double H = keyT + rowH * double(rows.size() + 1) + 16;

    auto X = [&](double s) {
        return plotL + (std::log10(std::max(s, 1e-3)) - std::log10(lo)) / (std::log10(hi) - std::log10(lo)) * (plotR - plotL);
    };
    auto Ymain = [&](double k) { return mainB - k / kt.back() * (mainB - mainT); };
    auto Ycull = [&](double k) { return cullB - k / ct.back() * (cullB - cullT); };

    std::ostringstream s;
    std::vector<Text> texts;
    s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << fmt(W) << "\" height=\"" << fmt(H, "%.0f")
      << "\" viewBox=\"0 0 " << fmt(W) << " " << fmt(H, "%.0f") << "\" font-family=\"sans-serif\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    texts.push_back({W / 2, 22, 15, "What accuracy costs: false keeps and false culls against bake time", "middle"});
    texts.back().bold = true;
    texts.push_back({plotL, mainT - 30, fs, "false keeps (bits written 1 that the reference proved 0: render time)"});
    texts.push_back({plotL + 14, mainT - 12, small, "false keeps", "start"});
    texts.push_back({plotL + 120, mainT - 12, small, "false culls (a defect at any setting)", "start"});
    s << "<circle cx=\"" << plotL + 6 << "\" cy=\"" << mainT - 16 << "\" r=\"4.5\" fill=\"#1f77b4\"/>\n";
    s << "<path d=\"M" << plotL + 108 << " " << mainT - 20 << " l8 8 m0 -8 l-8 8\" stroke=\"#d62728\" stroke-width=\"2.5\"/>\n";

    // Panels: frame, grid and ticks.
    for (const auto& [top, bottom, ticks, isMain] :
         {std::tuple{mainT, mainB, &kt, true}, std::tuple{cullT, cullB, &ct, false}}) {
        s << "<rect x=\"" << plotL << "\" y=\"" << top << "\" width=\"" << plotR - plotL << "\" height=\"" << bottom - top
          << "\" fill=\"" << (isMain ? "#fbfbfb" : "#fff6f6") << "\" stroke=\"#444\"/>\n";
        for (double v : *ticks) {
            const double y = isMain ? Ymain(v) : Ycull(v);
            s << "<line x1=\"" << plotL << "\" y1=\"" << fmt(y, "%.1f") << "\" x2=\"" << plotR << "\" y2=\"" << fmt(y, "%.1f")
              << "\" stroke=\"#ddd\"/>\n";
            texts.push_back({plotL - 8, y + 4, small, fmt(v), "end", true});
        }
        for (double v : xt)
            s << "<line x1=\"" << fmt(X(v), "%.1f") << "\" y1=\"" << top << "\" x2=\"" << fmt(X(v), "%.1f") << "\" y2=\""
              << bottom << "\" stroke=\"#e4e4e4\"/>\n";
    }
    texts.push_back({plotL, cullT - 8, small, "false culls (written 0 where the reference has a witness)"});
    texts.back().fill = "#a01010";
    for (double v : xt) texts.push_back({X(v), cullB + 16, small, fmt(v) + " s", "middle", true});
    texts.push_back({(plotL + plotR) / 2, xTitleY, fs, "bake time, seconds (log scale)", "middle"});

    // Markers, then their numbers (placed around every marker of the panel).
    LabelPlacer mainLabels({plotL + 2, mainT + 2, plotR - 2, mainB - 2}), cullLabels({plotL + 2, cullT + 2, plotR - 2, cullB - 2});
    for (const SweepRow& r : rows) {
        const double x = X(r.seconds);
        mainLabels.addObstacle({x - 6, Ymain(double(r.falseKeeps)) - 6, x + 6, Ymain(double(r.falseKeeps)) + 6});
        cullLabels.addObstacle({x - 6, Ycull(double(r.falseCulls)) - 6, x + 6, Ycull(double(r.falseCulls)) + 6});
    }
    for (size_t i = 0; i < rows.size(); ++i) {
        const SweepRow& r = rows[i];
        const double x = X(r.seconds), y = Ymain(double(r.falseKeeps)), yc = Ycull(double(r.falseCulls));
        s << "<circle cx=\"" << fmt(x, "%.1f") << "\" cy=\"" << fmt(y, "%.1f") << "\" r=\"5\" fill=\"#1f77b4\"><title>"
          << i + 1 << ": " << esc(r.setting) << "</title></circle>\n";
        if (r.falseCulls)
            s << "<path d=\"M" << fmt(x - 5, "%.1f") << " " << fmt(yc - 5, "%.1f") << " l10 10 m0 -10 l-10 10\" stroke=\"#d62728\" stroke-width=\"2.5\"/>\n";
        else
            s << "<circle cx=\"" << fmt(x, "%.1f") << "\" cy=\"" << fmt(yc, "%.1f") << "\" r=\"3.5\" fill=\"white\" stroke=\"#999\"/>\n";
    }
    for (size_t i = 0; i < rows.size(); ++i) {
        const SweepRow& r = rows[i];
        const double x = X(r.seconds);
        for (auto [placer, y, show] : {std::tuple{&mainLabels, Ymain(double(r.falseKeeps)), true},
                                       std::tuple{&cullLabels, Ycull(double(r.falseCulls)), r.falseCulls > 0}}) {
            if (!show) continue;
            bool leader = false;
            Text t = placer->place(x, y, std::to_string(i + 1), fs, leader);
            if (t.text.empty()) continue;
            if (leader) {
                const Box b = t.box();
                s << "<line x1=\"" << fmt(x, "%.1f") << "\" y1=\"" << fmt(y, "%.1f") << "\" x2=\""
                  << fmt(std::clamp(x, b.x0, b.x1), "%.1f") << "\" y2=\"" << fmt(std::clamp(y, b.y0, b.y1), "%.1f")
                  << "\" stroke=\"#888\" stroke-width=\"0.8\"/>\n";
            }
            texts.push_back(t);
        }
    }

    // Key table.
    const double kx = left;
    auto keyRow = [&](double y, const std::string& n, const std::string& name, const std::string& sec,
                      const std::string& keeps, const std::string& culls, bool head, bool bad) {
        for (auto [col, text, anchor] : {std::tuple{colNum + 2 * cw, n, "end"}, std::tuple{colName, name, "start"},
                                         std::tuple{colSec + 7 * cw, sec, "end"}, std::tuple{colKeep + 11 * cw, keeps, "end"},
                                         std::tuple{colCull + 11 * cw, culls, "end"}}) {
            Text t{kx + col, y, small, text, anchor, true};
            t.bold = head;
            if (bad) t.fill = "#a01010";
            texts.push_back(t);
        }
    };
    keyRow(keyT, "#", "setting", "seconds", "false keeps", "false culls", true, false);
    s << "<line x1=\"" << kx << "\" y1=\"" << keyT + 4 << "\" x2=\"" << kx + keyW << "\" y2=\"" << keyT + 4
      << "\" stroke=\"#888\"/>\n";
    for (size_t i = 0; i < rows.size(); ++i) {
        const SweepRow& r = rows[i];
        keyRow(keyT + rowH * double(i + 1), std::to_string(i + 1), r.setting, fmt(r.seconds, "%.3g"),
               std::to_string(r.falseKeeps), std::to_string(r.falseCulls), false, r.falseCulls > 0);
    }
    for (const Text& t : texts) s << t.svg();
    s << "</svg>\n";
    return s.str();
}

}  // namespace shadowcull::cli
