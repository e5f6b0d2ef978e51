// The picture of one changed group in `diff --html`: the group's box and the receivers its
// witness rays hit, from above and from the side, at one scale, with a scale bar and the
// light's direction. Only what the results recorded is drawn (boxes, rays, lights).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "cli/diff_model.h"

namespace shadowcull::cli::diff_detail {

namespace {

constexpr double kPanel = 280, kMargin = 18;  // panel side and inner margin, pixels

std::string f1(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f", v);
    return buf;
}

std::string escText(const std::string& s) {
    std::string o;
    for (char c : s) o += c == '&' ? "&amp;" : c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '"' ? "&quot;" : std::string(1, c);
    return o;
}

double dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// One view: world point -> (horizontal, vertical) in metres, vertical up.
struct Projection {
    Vec h, v;  // unit axes
    double x(const Vec& p) const { return dot(p, h); }
    double y(const Vec& p) const { return dot(p, v); }
};

// The 2-D rectangle a world box covers in a view (its corners' extremes: exact for these
// views, whose axes are a world axis and a horizontal direction).
void boxRect(const Projection& pr, const BoxVec& b, double& x0, double& y0, double& x1, double& y1) {
    x0 = y0 = 1e300, x1 = y1 = -1e300;
    for (int c = 0; c < 8; ++c) {
        const Vec p{(c & 1) ? b[1][0] : b[0][0], (c & 2) ? b[1][1] : b[0][1], (c & 4) ? b[1][2] : b[0][2]};
        x0 = std::min(x0, pr.x(p)), x1 = std::max(x1, pr.x(p));
        y0 = std::min(y0, pr.y(p)), y1 = std::max(y1, pr.y(p));
    }
}

double niceLength(double rough) {
    const double p = std::pow(10.0, std::floor(std::log10(rough)));
    double best = p;
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * p <= rough) best = m * p;
    return best;
}

struct Ray {
    const WitnessRay* w;
    bool isNew;
};

struct LightUse {
    int index;
    const LightInfo* info;
};

// One panel: boxes, rays, the lights' arrows, scale bar and axis names; `id` names its clip.
std::string panel(const std::string& id, const std::string& title, const Projection& pr, const std::string& hName,
                  const std::string& vName, double metresPerPx, const Vec& centre, const std::vector<BoxVec>& casters,
                  const std::vector<Ray>& rays, const std::vector<LightUse>& lights) {
    const double cx = pr.x(centre), cy = pr.y(centre);
    auto X = [&](double x) { return kPanel / 2 + (x - cx) / metresPerPx; };
    auto Y = [&](double y) { return kPanel / 2 + 8 - (y - cy) / metresPerPx; };
    std::string s = "<g><title>" + escText(title) + "</title><clipPath id=\"" + id + "\"><rect x=\"1\" y=\"1\" width=\"" +
                    f1(kPanel - 2) + "\" height=\"" + f1(kPanel - 2) + "\"/></clipPath>";
    s += "<rect x=\"0.5\" y=\"0.5\" width=\"" + f1(kPanel - 1) + "\" height=\"" + f1(kPanel - 1) + "\" class=\"frame\"/>";
    s += "<g clip-path=\"url(#" + id + ")\">";
    // Receivers first (they are large: a terrain), then the group, then the rays on top.
    std::set<std::string> drawn;
    for (const Ray& r : rays) {
        if (!r.w->receiverBounds) continue;
        const std::string key = r.w->receiver.substr(0, r.w->receiver.rfind(" group ")) + (r.isNew ? "n" : "o");
        if (!drawn.insert(key).second) continue;
        double x0, y0, x1, y1;
        boxRect(pr, *r.w->receiverBounds, x0, y0, x1, y1);
        s += "<rect class=\"recv " + std::string(r.isNew ? "new" : "old") + "\" x=\"" + f1(X(x0)) + "\" y=\"" + f1(Y(y1)) +
             "\" width=\"" + f1((x1 - x0) / metresPerPx) + "\" height=\"" + f1((y1 - y0) / metresPerPx) + "\"/>";
    }
    for (const BoxVec& b : casters) {
        double x0, y0, x1, y1;
        boxRect(pr, b, x0, y0, x1, y1);
        s += "<rect class=\"caster\" x=\"" + f1(X(x0)) + "\" y=\"" + f1(Y(y1)) + "\" width=\"" +
             f1(std::max((x1 - x0) / metresPerPx, 1.0)) + "\" height=\"" + f1(std::max((y1 - y0) / metresPerPx, 1.0)) + "\"/>";
    }
    for (const Ray& r : rays) {
        const std::string cls = r.isNew ? "new" : "old";
        const Vec &p = r.w->p, &q = r.w->q, &o = r.w->origin;
        s += "<line class=\"path " + cls + "\" x1=\"" + f1(X(pr.x(o))) + "\" y1=\"" + f1(Y(pr.y(o))) + "\" x2=\"" +
             f1(X(pr.x(p))) + "\" y2=\"" + f1(Y(pr.y(p))) + "\"/>";
        s += "<line class=\"" + cls + "\" x1=\"" + f1(X(pr.x(p))) + "\" y1=\"" + f1(Y(pr.y(p))) + "\" x2=\"" +
             f1(X(pr.x(q))) + "\" y2=\"" + f1(Y(pr.y(q))) + "\"/>";
        s += "<circle class=\"" + cls + " p\" cx=\"" + f1(X(pr.x(p))) + "\" cy=\"" + f1(Y(pr.y(p))) + "\" r=\"4\"/>";
        s += "<circle class=\"" + cls + " q\" cx=\"" + f1(X(pr.x(q))) + "\" cy=\"" + f1(Y(pr.y(q))) + "\" r=\"4\"/>";
    }
    s += "</g>";
    // The lights: where a light travels in this view, as an arrow in the top-right corner
    // (a point or spot light: from the light towards the group), named.
    double ay = kMargin + 8;
    for (const LightUse& L : lights) {
        Vec d{0, 0, 0};
        if (L.info && L.info->type == "directional" && L.info->direction) d = *L.info->direction;
        else if (L.info && L.info->position) d = {centre[0] - (*L.info->position)[0], centre[1] - (*L.info->position)[1],
                                                    centre[2] - (*L.info->position)[2]};
        const double len = std::sqrt(dot(d, d));
        const std::string name = "light " + std::to_string(L.index) + (L.info ? " '" + L.info->name + "'" : "");
        const double ex = kPanel - kMargin - 8;
        if (!(len > 0)) {
            s += "<text class=\"lbl\" x=\"" + f1(ex) + "\" y=\"" + f1(ay) + "\" text-anchor=\"end\">" + escText(name) +
                 ": direction not recorded</text>";
            ay += 16;
            continue;
        }
        const double dx = pr.x(d) / len, dy = -pr.y(d) / len, planar = std::hypot(dx, dy);
        const double cxA = ex - 22, cyA = ay + 22;
        if (planar < 0.2) {  // along the view axis: a dot (towards the viewer) or a cross
            const Vec toViewer{pr.h[1] * pr.v[2] - pr.h[2] * pr.v[1], pr.h[2] * pr.v[0] - pr.h[0] * pr.v[2],
                               pr.h[0] * pr.v[1] - pr.h[1] * pr.v[0]};
            const bool towards = dot(d, toViewer) > 0;
            s += "<circle class=\"light\" cx=\"" + f1(cxA) + "\" cy=\"" + f1(cyA) + "\" r=\"7\" fill=\"none\"/>";
            s += towards ? "<circle class=\"lightdot\" cx=\"" + f1(cxA) + "\" cy=\"" + f1(cyA) + "\" r=\"2.5\"/>"
                         : "<path class=\"light\" d=\"M" + f1(cxA - 5) + " " + f1(cyA - 5) + " l10 10 m0 -10 l-10 10\"/>";
        } else {
            const double ux = dx / planar * 20 * std::min(1.0, planar + 0.3), uy = dy / planar * 20 * std::min(1.0, planar + 0.3);
            s += "<line class=\"light\" x1=\"" + f1(cxA - ux) + "\" y1=\"" + f1(cyA - uy) + "\" x2=\"" + f1(cxA + ux) +
                 "\" y2=\"" + f1(cyA + uy) + "\" marker-end=\"url(#arrow)\"/>";
        }
        s += "<text class=\"lbl light\" x=\"" + f1(cxA - 30) + "\" y=\"" + f1(cyA + 4) + "\" text-anchor=\"end\">" +
             escText(name) + "</text>";
        ay += 50;
    }
    // Scale bar (bottom left) and the axes' names.
    const double bar = niceLength(kPanel / 4 * metresPerPx), barPx = bar / metresPerPx, by = kPanel - kMargin;
    s += "<path class=\"scale\" d=\"M" + f1(kMargin) + " " + f1(by - 4) + " v4 h" + f1(barPx) + " v-4\"/>";
    s += "<text class=\"lbl\" x=\"" + f1(kMargin + barPx / 2) + "\" y=\"" + f1(by - 7) + "\" text-anchor=\"middle\">" +
         num(bar) + " m</text>";
    s += "<text class=\"lbl axis\" x=\"" + f1(kPanel - kMargin + 10) + "\" y=\"" + f1(kPanel - 8) + "\" text-anchor=\"end\">" +
         escText(hName) + "</text>";
    s += "<text class=\"lbl axis\" x=\"8\" y=\"" + f1(kMargin) + "\">" + escText(vName) + "</text>";
    s += "<text class=\"lbl ttl\" x=\"" + f1(kPanel / 2) + "\" y=\"" + f1(kMargin - 2) + "\" text-anchor=\"middle\">" +
         escText(title) + "</text>";
    return s + "</g>";
}

}  // namespace

std::string groupPicture(const GroupChange& g, const Comparison& c, const Bake& a, const Bake& b, int id,
                         std::string& caption) {
    std::vector<Ray> rays;
    std::vector<BoxVec> casters;
    std::vector<LightUse> lights;
    bool maskOnly = false;
    for (const BitRow& r : g.rows) {
        if (r.before.witness) rays.push_back({&*r.before.witness, false});
        if (r.after.witness) rays.push_back({&*r.after.witness, true});
        maskOnly |= r.before.verdict.empty() || r.after.verdict.empty();
        const LightInfo* info = nullptr;
        if (size_t(r.light) <= b.lights.size()) info = &b.lights[size_t(r.light - 1)];
        else if (size_t(r.light) <= a.lights.size()) info = &a.lights[size_t(r.light - 1)];
        if (std::none_of(lights.begin(), lights.end(), [&](const LightUse& u) { return u.index == r.light; }) &&
            lights.size() < 3)
            lights.push_back({r.light, info});
    }
    (void)c;
    for (const Bake* side : {&a, &b}) {
        const auto ch = side->chunks.find(g.object.chunk);
        if (ch == side->chunks.end()) continue;
        for (const ObjectBake& o : ch->second.objects)
            if (o.key == g.object.key && size_t(g.group) < o.groups.size() && o.groups[size_t(g.group)].bounds &&
                (casters.empty() || casters.back() != *o.groups[size_t(g.group)].bounds))
                casters.push_back(*o.groups[size_t(g.group)].bounds);
    }
    if (rays.empty() && casters.empty()) {
        caption = maskOnly ? "No picture: a baked space records masks only (no rays, no boxes)."
                           : "No picture: this results file records no boxes, and neither side has a witness ray.";
        return "";
    }
    // Frame: the group and the witness points (a receiver may be a whole terrain: clipped).
    Vec lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    auto extend = [&](const Vec& p) {
        for (int k = 0; k < 3; ++k) lo[size_t(k)] = std::min(lo[size_t(k)], p[size_t(k)]), hi[size_t(k)] = std::max(hi[size_t(k)], p[size_t(k)]);
    };
    for (const BoxVec& bx : casters) extend(bx[0]), extend(bx[1]);
    for (const Ray& r : rays) extend(r.w->p), extend(r.w->q);
    const Vec centre{(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
    // The side view looks across the light's horizontal direction (the ray's slope shows
    // true); without one, across x.
    Vec h{1, 0, 0};
    if (!lights.empty() && lights[0].info) {
        Vec d{0, 0, 0};
        if (lights[0].info->direction && lights[0].info->type == "directional") d = *lights[0].info->direction;
        else if (lights[0].info->position)
            d = {centre[0] - (*lights[0].info->position)[0], 0, centre[2] - (*lights[0].info->position)[2]};
        const double l = std::hypot(d[0], d[2]);
        if (l > 1e-6) h = {d[0] / l, 0, d[2] / l};
    }
    const Projection top{{1, 0, 0}, {0, 0, -1}}, side{h, {0, 1, 0}};
    double extent = 2;
    for (const Projection* pr : {&top, &side})
        for (int c = 0; c < 8; ++c) {
            const Vec p{(c & 1) ? hi[0] : lo[0], (c & 2) ? hi[1] : lo[1], (c & 4) ? hi[2] : lo[2]};
            extent = std::max({extent, 2 * std::abs(pr->x(p) - pr->x(centre)), 2 * std::abs(pr->y(p) - pr->y(centre))});
        }
    const double metresPerPx = extent * 1.35 / (kPanel - 2 * kMargin - 20);
    std::string s = "<svg class=\"pic\" width=\"" + f1(2 * kPanel + 12) + "\" height=\"" + f1(kPanel) + "\" viewBox=\"0 0 " +
                    f1(2 * kPanel + 12) + " " + f1(kPanel) + "\"><defs><marker id=\"arrow\" viewBox=\"0 0 10 10\" refX=\"8\" "
                    "refY=\"5\" markerWidth=\"7\" markerHeight=\"7\" orient=\"auto-start-reverse\"><path d=\"M0 0 L10 5 L0 10 z\" "
                    "fill=\"#e08000\"/></marker></defs>";
    const std::string hText = "h (" + num(std::round(h[0] * 100) / 100) + ", 0, " + num(std::round(h[2] * 100) / 100) + ")";
    s += panel("t" + std::to_string(id), "from above", top, "x", "-z up", metresPerPx, centre, casters, rays, lights);
    s += "<g transform=\"translate(" + f1(kPanel + 12) + " 0)\">" +
         panel("s" + std::to_string(id), "from the side", side, hText, "y (up)", metresPerPx, centre, casters, rays, lights) +
         "</g>";
    caption = "Side view: " + hText + " to the right (across the light), y up.";
    if (casters.empty()) caption += " The group's box is not recorded.";
    if (rays.empty()) caption += " There is no witness ray on either side (proofs and undecided bits have none).";
    return s + "</svg>";
}

}  // namespace shadowcull::cli::diff_detail
