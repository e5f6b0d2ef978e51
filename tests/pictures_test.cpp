// What the pictures show a person (issue 15): `render` framed on the baked chunk with a
// legend whose counts are the verdicts', `check` pictures marking the disagreeing group,
// the `diff --html` lights, columns and witness pictures, the `sweep --svg` plot with no
// text outside its viewBox and no two labels overlapping, and the tiny bitmap font.

#include <png.h>

#include <cstring>
#include <regex>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "cli/check.h"
#include "cli/diff.h"
#include "cli/pipeline.h"
#include "cli/report.h"
#include "cli/sweep_plot.h"
#include "gpu/render.h"
#include "io/results_file.h"
#include "tests/support/gl_available.h"
#include "tests/support/space_builder.h"
#include "tests/support/thin_rod_check.h"
#include "tests/test_files.h"
#include "util/bitmap_font.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

struct Png {
    int width = 0, height = 0;
    std::vector<unsigned char> rgb;
    Rgb at(int x, int y) const {
        const size_t k = (size_t(y) * size_t(width) + size_t(x)) * 3;
        return {rgb[k], rgb[k + 1], rgb[k + 2]};
    }
};

Png readPng(const std::string& path) {
    png_image img{};
    img.version = PNG_IMAGE_VERSION;
    Png p;
    if (!png_image_begin_read_from_file(&img, path.c_str())) return p;
    img.format = PNG_FORMAT_RGB;
    p.rgb.resize(PNG_IMAGE_SIZE(img));
    if (!png_image_finish_read(&img, nullptr, p.rgb.data(), 0, nullptr)) p.rgb.clear();
    p.width = int(img.width), p.height = int(img.height);
    return p;
}

// A pixel of a centre-chunk group (red, green or yellow, shaded): clearly not grey.
bool verdictColoured(Rgb c) {
    const int hi = std::max({c.r, c.g, c.b}), lo = std::min({c.r, c.g, c.b});
    return hi > 60 && hi - lo > hi / 3;
}
bool magenta(Rgb c) { return c.r == 255 && c.g == 0 && c.b == 255; }

// Pixels of the view tiles matching `pred`, and their bounding box.
struct Found {
    int count = 0, x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
};
template <class Pred>
Found findInViews(const Png& png, const gpu::RenderReport& r, Pred pred) {
    Found f;
    for (int y = r.viewY; y < r.viewY + r.rows * r.tile; ++y)
        for (int x = r.viewX; x < r.viewX + r.cols * r.tile; ++x)
            if (pred(png.at(x, y))) {
                ++f.count;
                f.x0 = std::min(f.x0, x), f.y0 = std::min(f.y0, y), f.x1 = std::max(f.x1, x), f.y1 = std::max(f.y1, y);
            }
    return f;
}

Expected<cli::ChunkBake> bakeSampleChunk() {
    cli::BakeOptions opt;
    opt.spaceDir = std::string(SHADOWCULL_SOURCE_DIR) + "/data/sample";
    opt.write = false;
    return cli::bakeChunk(opt, ChunkCoord{0, 0});
}

std::string plural(uint64_t n) { return std::to_string(n) + (n == 1 ? " group" : " groups"); }

}  // namespace

TEST(BitmapFont, GlyphsAreDistinctAndTextIsDrawnWhereAsked) {
    std::set<std::vector<uint8_t>> shapes;
    for (char c = 33; c < 127; ++c) {
        uint8_t rows[kGlyphHeight];
        glyphRows(c, rows);
        EXPECT_TRUE(std::any_of(rows, rows + kGlyphHeight, [](uint8_t r) { return r != 0; })) << "glyph '" << c << "'";
        shapes.insert(std::vector<uint8_t>(rows, rows + kGlyphHeight));
    }
    // 'I' and 'l' and '1' may look alike in 5x7; almost every other glyph must be its own.
    EXPECT_GE(shapes.size(), 90u);
    RgbImage img(100, 30);
    const int end = drawText(img, 4, 4, "Hi", {255, 255, 255}, 2);
    EXPECT_EQ(end, 4 + 2 * kGlyphAdvance * 2);
    EXPECT_EQ(textWidth("Hi", 2), (2 * kGlyphAdvance - 1) * 2);
    int lit = 0, outside = 0;
    for (int y = 0; y < img.height(); ++y)
        for (int x = 0; x < img.width(); ++x) {
            if (img.at(x, y).r == 0) continue;
            ++lit;
            outside += x < 4 || x >= 4 + textWidth("Hi", 2) || y < 4 || y >= 4 + kGlyphHeight * 2;
        }
    EXPECT_GT(lit, 20);
    EXPECT_EQ(outside, 0);
    img.line(-50, -50, 500, 500, {1, 2, 3}, 3);  // clipped, no crash
}

// The sun view of the sample's centre chunk: the chunk (its groups are coloured by
// verdict, the neighbours grey) covers most of the view, not a corner of it as when the
// frame took in a balloon 1 km up; the legend's counts are the verdict table's.
TEST(RenderPicture, SunViewIsFramedOnTheChunkAndTheLegendCountsTheVerdicts) {
    REQUIRE_GL();
    Expected<cli::ChunkBake> cb = bakeSampleChunk();
    ASSERT_TRUE(cb) << cb.error().what();
    const fs::path dir = freshTestDir();
    for (int light : {0, 1}) {
        gpu::RenderRequest rq;
        rq.light = light;
        rq.resolution = 256;
        const std::string path = (dir / ("light" + std::to_string(light + 1) + ".png")).string();
        Expected<gpu::RenderReport> r = gpu::renderLightView(cb->window, cb->verdicts, rq, path);
        ASSERT_TRUE(r) << r.error().what();
        uint64_t culled = 0, kept = 0, undecided = 0;
        for (size_t oi = 0; oi < cb->verdicts.objects.size(); ++oi)
            for (int g = 0; g < cb->verdicts.objects[oi].groupCount; ++g) {
                const Verdict v = cb->verdicts.at(oi, g, light).verdict;
                ++(v == Verdict::Culled ? culled : v == Verdict::Kept ? kept : undecided);
            }
        EXPECT_EQ(r->culled, culled);
        EXPECT_EQ(r->kept, kept);
        EXPECT_EQ(r->undecided, undecided);
        ASSERT_GE(r->legend.size(), 4u);
        EXPECT_EQ(r->legend[0], "culled (proved 0): " + plural(culled));
        EXPECT_EQ(r->legend[1], "kept (proved 1, a witness): " + plural(kept));
        EXPECT_EQ(r->legend[2], "undecided (written 1, no proof): " + plural(undecided));
        ASSERT_GE(r->title.size(), 2u);
        EXPECT_NE(r->title[0].find("00000000o.chunk"), std::string::npos) << r->title[0];
        EXPECT_NE(r->title[0].find(light == 0 ? "light 1 'sun' (directional)" : "light 2 'lamp' (point)"),
                  std::string::npos)
            << r->title[0];
        const Png png = readPng(path);
        ASSERT_EQ(png.width, r->width);
        ASSERT_EQ(png.height, r->height);
        if (light == 0) {
            EXPECT_NE(r->title[1].find("light travels along (0.28, -0.94, 0.19)"), std::string::npos) << r->title[1];
            EXPECT_EQ(r->cols * r->rows, 1);
            const Found chunk = findInViews(png, *r, verdictColoured);
            const double cover = double(chunk.x1 - chunk.x0 + 1) * double(chunk.y1 - chunk.y0 + 1) / double(r->tile * r->tile);
            EXPECT_GT(cover, 0.7) << "the chunk's groups span " << chunk.x1 - chunk.x0 + 1 << " x " << chunk.y1 - chunk.y0 + 1
                                  << " px of " << r->tile << " x " << r->tile;
            EXPECT_GT(chunk.count, r->tile * r->tile / 2);
        } else {
            EXPECT_EQ(r->cols, 3);
            EXPECT_EQ(r->rows, 2);
        }
    }
}

// A group the caller asks for is outlined even where it is hidden (the cube under a roof);
// without outlines the picture has no outline colour anywhere in its views.
TEST(RenderPicture, OutlinesTheGroupsAskedForEvenWhenHidden) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    hiddenUnderRoof(Roof::Opaque).write((dir / "space").string());
    cli::BakeOptions opt;
    opt.spaceDir = (dir / "space").string();
    opt.write = false;
    Expected<cli::ChunkBake> cb = cli::bakeChunk(opt, ChunkCoord{0, 0});
    ASSERT_TRUE(cb) << cb.error().what();
    size_t cube = cb->verdicts.objects.size();
    for (size_t oi = 0; oi < cb->verdicts.objects.size(); ++oi)
        if (cb->verdicts.objects[oi].uuid == fixedUuid(1)) cube = oi;
    ASSERT_LT(cube, cb->verdicts.objects.size());
    gpu::RenderRequest rq;
    rq.resolution = 128;
    const std::string plain = (dir / "plain.png").string(), marked = (dir / "marked.png").string();
    Expected<gpu::RenderReport> r0 = gpu::renderLightView(cb->window, cb->verdicts, rq, plain);
    ASSERT_TRUE(r0) << r0.error().what();
    EXPECT_EQ(findInViews(readPng(plain), *r0, magenta).count, 0);
    rq.outlined = {{cube, 0}};
    rq.outlineMeaning = "asked for";
    Expected<gpu::RenderReport> r1 = gpu::renderLightView(cb->window, cb->verdicts, rq, marked);
    ASSERT_TRUE(r1) << r1.error().what();
    EXPECT_EQ(r1->outlined, 1u);
    const Found ring = findInViews(readPng(marked), *r1, magenta);
    EXPECT_GT(ring.count, 8);
    EXPECT_LT(double(ring.x1 - ring.x0) * double(ring.y1 - ring.y0), 0.5 * 128 * 128) << "around the cube, not the view";
    EXPECT_EQ(r1->legend.back(), "outlined: 1 group asked for");
}

// check's picture marks the rod the GPU method misses (thinner than a pixel: a ring where
// it lies), and the message says how many groups are outlined.
TEST(RenderPicture, CheckPictureMarksTheDisagreeingGroup) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    const ThinRodCheck check = checkThinRod(dir);
    EXPECT_EQ(check.code, 1) << check.out << check.err;
    EXPECT_NE(check.out.find("(1 disagreeing group outlined in magenta)"), std::string::npos) << check.out;
    const Png png = readPng((fs::path(check.opt.outDir) / "00000000o.chunk-light1.png").string());
    ASSERT_GT(png.width, 0);
    int ring = 0;
    for (int y = 0; y < png.height; ++y)
        for (int x = 0; x < png.width; ++x) ring += magenta(png.at(x, y));
    EXPECT_GT(ring, 40) << "a ring and the legend's swatch";
}

// --- diff --html -------------------------------------------------------------------------

namespace {

fs::path bakeToJson(const SpaceBuilder& b, const fs::path& dir, const std::string& name) {
    b.write((dir / (name + "-space")).string());
    cli::BakeOptions opt;
    opt.spaceDir = (dir / (name + "-space")).string();
    opt.write = false;
    Expected<cli::BakeResult> r = cli::runBake(opt);
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    const fs::path json = dir / (name + ".json");
    if (r) writeText(json, results::writeResults(cli::resultsFile(*r)));
    return json;
}

std::vector<std::string> matches(const std::string& text, const std::string& pattern) {
    std::vector<std::string> out;
    const std::regex re(pattern);
    for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
        out.push_back((*it)[1].str());
    return out;
}

}  // namespace

// A lamp's range went 25 -> 60: the text report, the Lights table's change column and the
// JSON say so; every column of the Lights and counts tables is filled, and no two columns
// of a table share a heading.
TEST(DiffHtml, LightChangesAndEveryColumnMeaningful) {
    const fs::path dir = freshTestDir();
    const fs::path a = bakeToJson(cubeBesideLamp(25), dir, "range25");
    const fs::path b = bakeToJson(cubeBesideLamp(60), dir, "range60");
    std::ostringstream out, err;
    const int code = cli::runDiff({a.string(), b.string(), (dir / "r.html").string(), (dir / "r.json").string()}, out, err);
    EXPECT_EQ(code, cli::kDiffChanged) << "a light's settings changed: " << out.str() << err.str();
    EXPECT_NE(out.str().find("light 1 'lamp' (point): range 25 -> 60 m"), std::string::npos) << out.str();
    const std::string html = readText(dir / "r.html");
    EXPECT_NE(html.find("<td>range 25 -&gt; 60 m</td>"), std::string::npos);
    EXPECT_NE(readText(dir / "r.json").find("\"change\": \"range 25 -> 60 m\""), std::string::npos);
    for (const std::string& table : matches(html, "(<table>[\\s\\S]*?</table>)")) {
        const std::vector<std::string> heads = matches(table, "<th>([^<]*)</th>");
        EXPECT_EQ(std::set<std::string>(heads.begin(), heads.end()).size(), heads.size()) << table;
    }
    const std::vector<std::string> tables = matches(html, "(<table>[\\s\\S]*?</table>)");
    ASSERT_GE(tables.size(), 2u);
    for (size_t t : {size_t(0), size_t(1)}) {  // Lights, counts per chunk
        const std::vector<std::string> cells = matches(tables[t], "<td[^>]*>([^<]*)</td>");
        ASSERT_FALSE(cells.empty());
        for (const std::string& c : cells) EXPECT_FALSE(c.empty()) << tables[t];
    }
}

// A witness lost (range 10 -> 5): the group's picture draws the cube's box, the terrain the
// old witness lands on, the ray, a scale bar and the light's direction, from above and from
// the side; every text of the picture lies inside its panel.
TEST(DiffHtml, WitnessPictureShowsTheObjectTheReceiverScaleAndLight) {
    const fs::path dir = freshTestDir();
    const fs::path a = bakeToJson(cubeBesideLamp(10), dir, "range10");
    const fs::path b = bakeToJson(cubeBesideLamp(5), dir, "range5");
    std::ostringstream out, err;
    EXPECT_EQ(cli::runDiff({a.string(), b.string(), (dir / "r.html").string(), ""}, out, err), cli::kDiffChanged);
    const std::string html = readText(dir / "r.html");
    const std::vector<std::string> svgs = matches(html, "(<svg class=\"pic\"[\\s\\S]*?</svg>)");
    ASSERT_EQ(svgs.size(), 1u) << html;
    const std::string& svg = svgs[0];
    EXPECT_EQ(matches(svg, "(<rect class=\"caster\")").size(), 2u) << "the cube's box, from above and from the side";
    EXPECT_EQ(matches(svg, "(<rect class=\"recv old\")").size(), 2u) << "the terrain's box";
    EXPECT_EQ(matches(svg, "(<circle class=\"old p\")").size(), 2u);
    EXPECT_EQ(matches(svg, "(marker-end=\"url\\(#arrow\\)\")").size(), 2u) << "the lamp's direction in both views";
    EXPECT_EQ(matches(svg, "(<path class=\"scale\")").size(), 2u);
    EXPECT_EQ(matches(svg, ">([0-9.]+ m)</text>").size(), 2u) << "scale bars are labelled in metres";
    EXPECT_NE(svg.find("from above"), std::string::npos);
    EXPECT_NE(svg.find("from the side"), std::string::npos);
    // Text anchors inside the 280 px panels (labels are short; the long words are in HTML).
    const std::regex text("<text[^>]* x=\"([-0-9.]+)\" y=\"([-0-9.]+)\"[^>]*>([^<]*)</text>");
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), text); it != std::sregex_iterator(); ++it) {
        const double x = std::stod((*it)[1].str()), y = std::stod((*it)[2].str());
        EXPECT_TRUE(x >= 0 && x <= 280 && y >= 8 && y <= 280) << (*it)[0].str();
    }
}

// --- sweep --svg ---------------------------------------------------------------------------

namespace {

struct TextBox {
    double x0, y0, x1, y1;
    std::string text;
};

// The boxes of the SVG's text elements, from the attributes the plot writes (x, y,
// font-size, text-anchor), with the plot's own width estimate for monospace and sans text
// (0.6 em a character), ascent 0.8 em, descent 0.25 em.
std::vector<TextBox> textBoxes(const std::string& svg) {
    std::vector<TextBox> boxes;
    const std::regex re("<text x=\"([-0-9.]+)\" y=\"([-0-9.]+)\" font-size=\"([0-9.]+)\" text-anchor=\"(\\w+)\"[^>]*>([^<]*)</text>");
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), re); it != std::sregex_iterator(); ++it) {
        const double x = std::stod((*it)[1]), y = std::stod((*it)[2]), f = std::stod((*it)[3]);
        std::string t = (*it)[5];
        for (const char* e : {"&amp;", "&lt;", "&gt;"})
            for (size_t k; (k = t.find(e)) != std::string::npos;) t.replace(k, std::strlen(e), "x");
        const double w = double(t.size()) * 0.6 * f;
        const std::string anchor = (*it)[4];
        const double x0 = anchor == "start" ? x : anchor == "middle" ? x - w / 2 : x - w;
        boxes.push_back({x0, y - 0.8 * f, x0 + w, y + 0.25 * f, t});
    }
    return boxes;
}

void expectReadablePlot(const std::vector<cli::SweepRow>& rows) {
    const std::string svg = cli::sweepSvg(rows);
    std::smatch m;
    ASSERT_TRUE(std::regex_search(svg, m, std::regex("viewBox=\"0 0 ([0-9.]+) ([0-9.]+)\"")));
    const double W = std::stod(m[1]), H = std::stod(m[2]);
    const std::vector<TextBox> boxes = textBoxes(svg);
    ASSERT_EQ(size_t(std::count(svg.begin(), svg.end(), '\n')) > boxes.size(), true);
    EXPECT_EQ(boxes.size(), size_t(matches(svg, "(<text )").size())) << "every text element has the attributes";
    for (const TextBox& b : boxes) EXPECT_TRUE(b.x0 >= 0 && b.y0 >= 0 && b.x1 <= W && b.y1 <= H) << "'" << b.text << "' outside";
    for (size_t i = 0; i < boxes.size(); ++i)
        for (size_t k = i + 1; k < boxes.size(); ++k) {
            const TextBox &a = boxes[i], &b = boxes[k];
            const bool overlap = a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1;
            EXPECT_FALSE(overlap) << "'" << a.text << "' overlaps '" << b.text << "'";
        }
    // Every point numbered and in the key; every setting's full name present.
    for (size_t i = 0; i < rows.size(); ++i) EXPECT_NE(svg.find(">" + rows[i].setting + "<"), std::string::npos);
}

cli::SweepRow row(const std::string& name, double seconds, uint64_t keeps, uint64_t culls) {
    cli::SweepRow r;
    r.setting = name, r.seconds = seconds, r.falseKeeps = keeps, r.falseCulls = culls;
    return r;
}

}  // namespace

TEST(SweepSvg, NiceTicks) {
    EXPECT_EQ(cli::niceLinearTicks(5), (std::vector<double>{0, 2, 4, 6}));
    EXPECT_EQ(cli::niceLinearTicks(0), (std::vector<double>{0, 1}));
    EXPECT_EQ(cli::niceLinearTicks(37), (std::vector<double>{0, 10, 20, 30, 40}));
    EXPECT_EQ(cli::niceLogTicks(0.03, 30), (std::vector<double>{0.05, 0.1, 0.2, 0.5, 1, 2, 5, 10, 20}));
    EXPECT_EQ(cli::niceLogTicks(0.001, 1000).size(), 7u) << "decades only over many decades";
}

// The sample's sweep (figures of docs/performance.md), and a crowded one: many settings at
// the same time and count, long names.
TEST(SweepSvg, NoTextOutsideTheViewBoxAndNoLabelsOverlap) {
    expectReadablePlot({row("raycast, 16 samples", 0.036, 5, 0), row("raycast, 64 samples", 0.037, 5, 0),
                        row("raycast, 256 samples", 0.038, 5, 0), row("raycast, 1024 samples", 0.047, 5, 0),
                        row("raycast+geometry, 16 samples", 0.09, 2, 0), row("raycast+geometry, 64 samples", 0.085, 2, 0),
                        row("raycast+geometry, 256 samples", 0.092, 2, 0), row("raycast+geometry, 1024 samples", 0.111, 2, 0),
                        row("raycast+geometry+gpu, 256 samples, 512 px", 0.198, 0, 0),
                        row("raycast+geometry+gpu, 256 samples, 1024 px", 0.265, 0, 0),
                        row("raycast+geometry+gpu, 256 samples, 2048 px", 0.567, 0, 0),
                        row("original GPU method, 512 px", 0.988, 0, 4), row("original GPU method, 1024 px", 1.664, 0, 2),
                        row("original GPU method, 2048 px", 5.88, 0, 0), row("original GPU method, 4096 px", 23.96, 0, 0)});
    std::vector<cli::SweepRow> crowded;
    for (int i = 0; i < 24; ++i)
        crowded.push_back(row("a rather long setting name number " + std::to_string(i) + ", 1024 samples, 4096 px",
                              1.0 + 0.01 * i, uint64_t(1000 + i % 3), uint64_t(i % 4)));
    expectReadablePlot(crowded);
    expectReadablePlot({row("only one", 2.0, 0, 0)});
}
