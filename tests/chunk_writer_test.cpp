// The <shadow> writer: every byte outside the <shadow> spans survives, rewrites are
// idempotent, malformed files are refused with a line number, and files are replaced
// atomically.

#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "io/chunk_writer.h"
#include "tests/test_files.h"

using namespace shadowcull;
using shadowcull::testing::freshTestDir;
using shadowcull::testing::readText;
using shadowcull::testing::writeText;
namespace fs = std::filesystem;

namespace {

ShadowWrite model(std::vector<uint32_t> groups) {
    ShadowWrite w;
    for (uint32_t g : groups) w.mask |= g;
    w.groupMasks = std::move(groups);
    return w;
}

ShadowWrite terrain(uint32_t mask) {
    ShadowWrite w;
    w.terrain = true;
    w.mask = mask;
    return w;
}

ShadowWrite keep(bool isTerrain = false) {
    ShadowWrite w;
    w.write = false;
    w.terrain = isTerrain;
    return w;
}

std::string rewrite(const std::string& xml, const std::vector<ShadowWrite>& objects) {
    Expected<std::string> r = rewriteChunkShadows(xml, "chunk.xml", objects);
    EXPECT_TRUE(r.isOk()) << (r ? "" : r.error().what());
    return r ? *r : "<rewrite failed>";
}

std::string crlf(const std::string& s) {
    std::string out;
    for (char c : s) out += c == '\n' ? std::string("\r\n") : std::string(1, c);
    return out;
}

// The full contract for one input: the expected output, a fixed point on a second run,
// and the input unchanged when nothing is written.
void expectRewrite(const std::string& input, const std::vector<ShadowWrite>& objects, const std::string& expected) {
    std::string out = rewrite(input, objects);
    EXPECT_EQ(out, expected);
    EXPECT_EQ(rewrite(out, objects), out) << "second rewrite is not a fixed point";
    std::vector<ShadowWrite> none;
    for (const ShadowWrite& w : objects) none.push_back(keep(w.terrain));
    EXPECT_EQ(rewrite(input, none), input);
}

// The multi-line model layout, with `ind` the <shadow> line's indentation.
std::string modelShadow(const std::string& ind, const std::string& unit, uint32_t mask,
                        const std::vector<uint32_t>& groups, const std::string& eol = "\n") {
    std::string s = "<shadow> " + std::to_string(mask) + eol + ind + unit + "<RenderSet>" + eol + ind + unit + unit +
                    "<Geometry>" + eol;
    for (uint32_t g : groups)
        s += ind + unit + unit + unit + "<PrimitiveGroup> " + std::to_string(g) + " </PrimitiveGroup>" + eol;
    return s + ind + unit + unit + "</Geometry>" + eol + ind + unit + "</RenderSet>" + eol + ind + "</shadow>";
}

// ---------------------------------------------------------------- byte preservation

// A file with most of what XML allows: only the two shadow spans may change.
const std::string kRichHead =
    "\xEF\xBB\xBF<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
    "<!DOCTYPE chunk [\n"
    "  <!ENTITY note \"a > b\">\n"
    "  <!-- a comment with ] and > inside -->\n"
    "]>\n"
    "<!-- written by hand; <model> here is no element -->\n"
    "<chunk  version='2' note=\"x > y / z\" >\n"
    "  <?editor keep this ?>\n"
    "  <unknown a='1' b=\"it's > 0\"><model><shadow>9</shadow></model></unknown>\n"
    "  <model id=\"a\"  path='/m/a.model'>\n"
    "    <resource> a.model </resource>\n"
    "    <!-- old shadow follows: <shadow> 1 </shadow> -->\n"
    "    ";
const std::string kRichOldShadow = "<shadow>  1  <RenderSet/> </shadow>";
const std::string kRichMiddle =
    "\n"
    "    <notes><![CDATA[ <model> </terrain> ]]></notes>\n"
    "  </model>\n"
    "  <!-- between models -->\n"
    "  <model>\n"
    "    <resource>b.model</resource>\n"
    "    <extra k = \"v/>\" j='>'/>\n";
const std::string kRichTail = "  </model>\n</chunk>\n<!-- trailing comment -->\n";

TEST(ChunkWriter, RichFileChangesOnlyTheShadowSpans) {
    std::string input = kRichHead + kRichOldShadow + kRichMiddle + kRichTail;
    std::string expected = kRichHead + modelShadow("    ", "  ", 3, {1, 2}) + kRichMiddle + "    " +
                           modelShadow("    ", "  ", 4, {4}) + "\n" + kRichTail;
    expectRewrite(input, {model({1, 2}), model({4})}, expected);
}

TEST(ChunkWriter, RichFileWithCrlfKeepsCrlfEverywhere) {
    std::string input = crlf(kRichHead + kRichOldShadow + kRichMiddle + kRichTail);
    std::string expected = crlf(kRichHead + modelShadow("    ", "  ", 3, {1, 2}) + kRichMiddle + "    " +
                                modelShadow("    ", "  ", 4, {4}) + "\n" + kRichTail);
    std::string out = rewrite(input, {model({1, 2}), model({4})});
    EXPECT_EQ(out, expected);
    size_t lf = 0, crlfs = 0;
    for (size_t i = 0; i < out.size(); ++i) {
        lf += out[i] == '\n';
        crlfs += out[i] == '\n' && i > 0 && out[i - 1] == '\r';
    }
    EXPECT_EQ(lf, crlfs) << "a line ends in a lone LF";
    expectRewrite(input, {model({1, 2}), model({4})}, expected);
}

TEST(ChunkWriter, TabIndentedFileGetsTabs) {
    std::string head = "<chunk>\n\t<model>\n\t\t<resource>a</resource>\n";
    std::string tail = "\t</model>\n</chunk>\n";
    expectRewrite(head + tail, {model({1, 0})}, head + "\t\t" + modelShadow("\t\t", "\t", 1, {1, 0}) + "\n" + tail);
}

TEST(ChunkWriter, MissingFinalNewlineStaysMissing) {
    std::string head = "<chunk>\n  <terrain>\n    <resource>t</resource>\n";
    std::string tail = "  </terrain>\n</chunk>";
    expectRewrite(head + tail, {terrain(5)}, head + "    <shadow> 5 </shadow>\n" + tail);
    expectRewrite(crlf(head + tail), {terrain(5)}, crlf(head + "    <shadow> 5 </shadow>\n" + tail));
}

TEST(ChunkWriter, WriteFalseLeavesThatElementAlone) {
    std::string input =
        "<chunk>\n"
        "  <model>\n    <shadow> 7 </shadow>\n    <shadow> 8 </shadow>\n  </model>\n"
        "  <terrain>\n  </terrain>\n"
        "  <model>\n  </model>\n"
        "</chunk>\n";
    std::string expected =
        "<chunk>\n"
        "  <model>\n    <shadow> 7 </shadow>\n    <shadow> 8 </shadow>\n  </model>\n"
        "  <terrain>\n    <shadow> 1 </shadow>\n  </terrain>\n"
        "  <model>\n  </model>\n"
        "</chunk>\n";
    expectRewrite(input, {keep(), terrain(1), keep()}, expected);
}

// ---------------------------------------------------------------- replacement and removal

TEST(ChunkWriter, ReplacesSingleLineShadowInPlace) {
    std::string head = "<c>\n  <model>\n    <resource>a</resource>\n    ";
    std::string tail = "\n    <after/>\n  </model>\n</c>\n";
    expectRewrite(head + "<shadow> 1 </shadow>" + tail, {model({2, 1})},
                  head + modelShadow("    ", "  ", 3, {2, 1}) + tail);
}

TEST(ChunkWriter, ReplacesMultiLineShadowInPlace) {
    std::string head = "<c>\n  <model>\n    ";
    std::string tail = "\n  </model>\n</c>\n";
    std::string old = modelShadow("    ", "  ", 7, {1, 2, 4});
    expectRewrite(head + old + tail, {model({2})}, head + modelShadow("    ", "  ", 2, {2}) + tail);
    // A self-closing shadow is replaced too.
    expectRewrite(head + "<shadow/>" + tail, {model({})}, head + "<shadow> 0 </shadow>" + tail);
}

TEST(ChunkWriter, RemovesFurtherShadowsWithoutLeavingBlankLines) {
    std::string input =
        "<c>\n  <terrain>\n"
        "    <shadow>1</shadow>\n"
        "    <a/>\n"
        "    <shadow>2</shadow>\n"
        "\t  <shadow>\n      3\n    </shadow>\n"
        "    <b/> <shadow x='1'/>\n"
        "  </terrain>\n</c>\n";
    std::string expected =
        "<c>\n  <terrain>\n"
        "    <shadow> 5 </shadow>\n"
        "    <a/>\n"
        "    <b/>\n"
        "  </terrain>\n</c>\n";
    expectRewrite(input, {terrain(5)}, expected);
    expectRewrite(crlf(input), {terrain(5)}, crlf(expected));
}

// ---------------------------------------------------------------- insertion

TEST(ChunkWriter, InsertsAfterLastChildWithItsIndentation) {
    std::string head = "<c>\n  <model>\n      <resource>a</resource>\n";
    std::string tail = "  </model>\n</c>\n";
    expectRewrite(head + tail, {model({1})}, head + "      " + modelShadow("      ", "  ", 1, {1}) + "\n" + tail);
}

TEST(ChunkWriter, InsertsIntoElementWithoutChildren) {
    expectRewrite("<c>\n  <terrain>\n  </terrain>\n</c>\n", {terrain(2)},
                  "<c>\n  <terrain>\n    <shadow> 2 </shadow>\n  </terrain>\n</c>\n");
    expectRewrite("<c>\n  <terrain>\n\n</terrain>\n</c>\n", {terrain(2)},
                  "<c>\n  <terrain>\n\n    <shadow> 2 </shadow>\n</terrain>\n</c>\n");
}

TEST(ChunkWriter, InsertsWhenEndTagSharesALine) {
    // The end tag gets its own line, indented like the start tag.
    expectRewrite("<c>\n  <terrain>\n    <resource>t</resource></terrain>\n</c>\n", {terrain(3)},
                  "<c>\n  <terrain>\n    <resource>t</resource>\n    <shadow> 3 </shadow>\n  </terrain>\n</c>\n");
    // A child on the start tag's line says nothing about indentation: one unit in.
    expectRewrite("<c>\n  <terrain><resource>t</resource>\n  </terrain>\n</c>\n", {terrain(3)},
                  "<c>\n  <terrain><resource>t</resource>\n    <shadow> 3 </shadow>\n  </terrain>\n</c>\n");
}

TEST(ChunkWriter, ExpandsSelfClosingElementOnItsOwnLine) {
    std::string input = "<c>\n  <model a=\"1\" />\n  <terrain/>\n</c>\n";
    std::string expected = "<c>\n  <model a=\"1\">\n    " + modelShadow("    ", "  ", 2, {2}) +
                           "\n  </model>\n  <terrain>\n    <shadow> 6 </shadow>\n  </terrain>\n</c>\n";
    expectRewrite(input, {model({2}), terrain(6)}, expected);
}

TEST(ChunkWriter, ElementsOnOneLineGetAnInlineShadow) {
    expectRewrite("<c><model/><terrain/></c>", {model({3}), terrain(1)},
                  "<c><model> <shadow> 3 <RenderSet> <Geometry> <PrimitiveGroup> 3 </PrimitiveGroup> </Geometry> "
                  "</RenderSet> </shadow> </model><terrain> <shadow> 1 </shadow> </terrain></c>");
    expectRewrite("<c>\n  <model><resource>a</resource></model>\n  <terrain> </terrain>\n</c>\n",
                  {model({2, 0}), terrain(7)},
                  "<c>\n  <model><resource>a</resource> <shadow> 2 <RenderSet> <Geometry> <PrimitiveGroup> 2 "
                  "</PrimitiveGroup> <PrimitiveGroup> 0 </PrimitiveGroup> </Geometry> </RenderSet> </shadow> "
                  "</model>\n  <terrain> <shadow> 7 </shadow> </terrain>\n</c>\n");
    // An existing inline shadow stays inline.
    expectRewrite("<c><terrain><shadow>1</shadow><x/></terrain></c>", {terrain(9)},
                  "<c><terrain><shadow> 9 </shadow><x/></terrain></c>");
}

// ---------------------------------------------------------------- values

TEST(ChunkWriter, MaskValuesAreDecimalUpToUint32Max) {
    const std::string input = "<c>\n  <terrain>\n  </terrain>\n</c>\n";
    for (uint32_t m : {0u, 2u, 3u, 4294967295u})
        expectRewrite(input, {terrain(m)},
                      "<c>\n  <terrain>\n    <shadow> " + std::to_string(m) + " </shadow>\n  </terrain>\n</c>\n");
    EXPECT_EQ(rewrite("<c><terrain/></c>", {terrain(4294967295u)}),
              "<c><terrain> <shadow> 4294967295 </shadow> </terrain></c>");

    std::string out = rewrite("<c>\n  <model>\n  </model>\n</c>\n", {model({0, 2, 3, 4294967295u})});
    EXPECT_EQ(out, "<c>\n  <model>\n    " + modelShadow("    ", "  ", 4294967295u, {0, 2, 3, 4294967295u}) +
                       "\n  </model>\n</c>\n");
    EXPECT_NE(out.find("<shadow> 4294967295\n"), std::string::npos);
    EXPECT_NE(out.find("<PrimitiveGroup> 0 </PrimitiveGroup>"), std::string::npos);
}

TEST(ChunkWriter, ModelWithoutGroupsGetsTheShortForm) {
    expectRewrite("<c>\n  <model>\n  </model>\n</c>\n", {model({})},
                  "<c>\n  <model>\n    <shadow> 0 </shadow>\n  </model>\n</c>\n");
}

// ---------------------------------------------------------------- structure

TEST(ChunkWriter, OnlyDirectChildrenOfTheRootCount) {
    std::string input =
        "<c>\n"
        "  <group>\n    <model>\n    </model>\n    <terrain/>\n  </group>\n"
        "  <model>\n    <lod><shadow>1</shadow></lod>\n  </model>\n"
        "</c>\n";
    std::string expected =
        "<c>\n"
        "  <group>\n    <model>\n    </model>\n    <terrain/>\n  </group>\n"
        "  <model>\n    <lod><shadow>1</shadow></lod>\n    <shadow> 0 </shadow>\n  </model>\n"
        "</c>\n";
    expectRewrite(input, {model({})}, expected);
}

TEST(ChunkWriter, RootMayHaveAnyName) {
    expectRewrite("<world>\n  <terrain>\n  </terrain>\n</world>\n", {terrain(1)},
                  "<world>\n  <terrain>\n    <shadow> 1 </shadow>\n  </terrain>\n</world>\n");
    expectRewrite("<x:chunk xmlns:x='urn:x'>\n  <terrain/>\n</x:chunk>", {terrain(1)},
                  "<x:chunk xmlns:x='urn:x'>\n  <terrain>\n    <shadow> 1 </shadow>\n  </terrain>\n</x:chunk>");
    // A root named like an object is still the root, not an object.
    expectRewrite("<model>\n  <terrain/>\n</model>\n", {terrain(1)},
                  "<model>\n  <terrain>\n    <shadow> 1 </shadow>\n  </terrain>\n</model>\n");
}

TEST(ChunkWriter, ObjectCountMismatchIsBadInput) {
    const std::string input = "<!-- x -->\n<c>\n  <model/>\n  <terrain/>\n</c>\n";
    for (size_t n : {0, 1, 3}) {
        Expected<std::string> r = rewriteChunkShadows(input, "a/chunk.xml", std::vector<ShadowWrite>(n, keep()));
        ASSERT_FALSE(r.isOk()) << n;
        EXPECT_EQ(r.error().kind, ErrorKind::BadInput);
        EXPECT_EQ(r.error().file, "a/chunk.xml");
        EXPECT_EQ(r.error().line, 2);
        EXPECT_NE(r.error().message.find("has 2"), std::string::npos) << r.error().message;
    }
}

TEST(ChunkWriter, ObjectKindMismatchIsBadInput) {
    Expected<std::string> r = rewriteChunkShadows("<c>\n  <model/>\n</c>\n", "chunk.xml", {terrain(1)});
    ASSERT_FALSE(r.isOk());
    EXPECT_EQ(r.error().kind, ErrorKind::BadInput);
    EXPECT_EQ(r.error().line, 2);
}

struct Malformed {
    const char* xml;
    int line;
    const char* words;  // part of the expected message
};

TEST(ChunkWriter, MalformedXmlNamesTheLine) {
    const Malformed cases[] = {
        {"<c>\n  <model>\n</c>\n", 3, "does not match <model>"},
        {"<c>\n  <model>\n  </model>\n", 1, "never closed"},
        {"<c>\n  <model>\n    <a>\n  </model>\n</c>\n", 4, "does not match <a>"},
        {"<c>\n</c>\ntext\n", 3, "after the root"},
        {"stray\n<c/>\n", 1, "before the root"},
        {"<c/>\n\n<d/>\n", 3, "second root"},
        {"<c>\n</c>\n</d>\n", 3, "without a start tag"},
        {"<c>\n<!-- open\n</c>", 2, "unclosed comment"},
        {"<c>\n<![CDATA[ x\n</c>", 2, "unclosed CDATA"},
        {"<?xml version='1.0'\n<c/>", 1, "unclosed processing instruction"},
        {"<!DOCTYPE c [\n<c/>", 1, "unclosed DOCTYPE"},
        {"<c>\n  <model a=\"1>\n</c>\n", 2, "unclosed attribute"},
        {"<c>\n\n  <model a=1/>\n</c>", 3, "unquoted"},
        {"<c>\n  <model a/>\n</c>", 2, "malformed attribute"},
        {"<c>\n  <model\n", 2, "unclosed start tag"},
        {"<c>\n  < model/>\n</c>", 2, "element name"},
        {"<c>\n  <model></model\n</c>", 2, "malformed end tag"},
        {"<c>\n  <!ELEMENT c ANY>\n</c>", 2, "unexpected markup"},
        {"", 1, "no root"},
        {"\n\n<!-- only -->\n", 3, "no root"},
    };
    for (const Malformed& m : cases) {
        Expected<std::string> r = rewriteChunkShadows(m.xml, "bad.xml", {});
        ASSERT_FALSE(r.isOk()) << m.xml;
        EXPECT_EQ(r.error().kind, ErrorKind::BadInput) << m.xml;
        EXPECT_EQ(r.error().line, m.line) << m.xml << "\n" << r.error().what();
        EXPECT_EQ(r.error().what().rfind("bad.xml:" + std::to_string(m.line) + ": ", 0), 0u) << r.error().what();
        EXPECT_NE(r.error().message.find(m.words), std::string::npos) << r.error().message;
    }
}

// ---------------------------------------------------------------- atomic writing

TEST(AtomicWrite, TempPathIsAHiddenSibling) {
    EXPECT_EQ(tempPathFor("a/b/c.xml"), "a/b/.c.xml.shadowcull-tmp");
    EXPECT_EQ(tempPathFor("c.xml"), ".c.xml.shadowcull-tmp");
    EXPECT_EQ(tempPathFor("/c.xml"), "/.c.xml.shadowcull-tmp");
}

TEST(AtomicWrite, WritesContentsAndLeavesNoTemp) {
    fs::path dir = freshTestDir();
    fs::path p = dir / "chunk.xml";
    std::string binary("a\0b\r\n\xEF\xBB\xBF", 8);
    ASSERT_TRUE(writeFileAtomic(p.string(), binary).isOk());
    EXPECT_EQ(readText(p), binary);
    // Replacing a longer file leaves nothing of the old one.
    ASSERT_TRUE(writeFileAtomic(p.string(), "x").isOk());
    EXPECT_EQ(readText(p), "x");
    ASSERT_TRUE(writeFileAtomic(p.string(), "").isOk());
    EXPECT_EQ(readText(p), "");
    EXPECT_FALSE(fs::exists(tempPathFor(p.string())));
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(AtomicWrite, PreservesPermissionBits) {
    fs::path dir = freshTestDir();
    for (mode_t mode : {mode_t(0640), mode_t(0755), mode_t(0600)}) {
        fs::path p = dir / ("f" + std::to_string(mode));
        writeText(p, "old");
        ASSERT_EQ(::chmod(p.c_str(), mode), 0);
        ASSERT_TRUE(writeFileAtomic(p.string(), "new").isOk());
        struct stat st {};
        ASSERT_EQ(::stat(p.c_str(), &st), 0);
        EXPECT_EQ(st.st_mode & 07777, mode);
        EXPECT_EQ(readText(p), "new");
    }
}

TEST(AtomicWrite, PathThatIsADirectoryFailsAndLeavesItAlone) {
    fs::path dir = freshTestDir();
    fs::path target = dir / "sub";
    fs::create_directory(target);
    writeText(target / "inside", "keep");
    Status s = writeFileAtomic(target.string(), "data");
    ASSERT_FALSE(s.isOk());
    EXPECT_EQ(s.error().kind, ErrorKind::Io);
    EXPECT_NE(s.error().what().find(target.string()), std::string::npos) << s.error().what();
    EXPECT_TRUE(fs::is_directory(target));
    EXPECT_EQ(readText(target / "inside"), "keep");
    EXPECT_FALSE(fs::exists(tempPathFor(target.string())));
}

TEST(AtomicWrite, MissingDirectoryFails) {
    fs::path p = freshTestDir() / "missing" / "chunk.xml";
    Status s = writeFileAtomic(p.string(), "data");
    ASSERT_FALSE(s.isOk());
    EXPECT_EQ(s.error().kind, ErrorKind::Io);
    EXPECT_NE(s.error().what().find(p.string()), std::string::npos);
    EXPECT_NE(s.error().what().find("No such file"), std::string::npos) << s.error().what();
}

TEST(AtomicWrite, ReadOnlyDirectoryFailsAndLeavesOriginal) {
    if (::geteuid() == 0) GTEST_SKIP() << "root can write into read-only directories";
    fs::path dir = freshTestDir() / "ro";
    fs::path p = dir / "chunk.xml";
    writeText(p, "original");
    ASSERT_EQ(::chmod(dir.c_str(), 0555), 0);
    Status s = writeFileAtomic(p.string(), "new");
    ::chmod(dir.c_str(), 0755);
    ASSERT_FALSE(s.isOk());
    EXPECT_EQ(s.error().kind, ErrorKind::Io);
    EXPECT_EQ(readText(p), "original");
    EXPECT_FALSE(fs::exists(tempPathFor(p.string())));
}

TEST(AtomicWrite, BlockedTempPathFailsAndLeavesOriginal) {
    // Runs as root too, unlike the read-only directory case: the temporary cannot be created.
    fs::path dir = freshTestDir();
    fs::path p = dir / "chunk.xml";
    writeText(p, "original");
    fs::create_directory(tempPathFor(p.string()));
    Status s = writeFileAtomic(p.string(), "new");
    ASSERT_FALSE(s.isOk());
    EXPECT_EQ(s.error().kind, ErrorKind::Io);
    EXPECT_EQ(s.error().file, p.string());
    EXPECT_EQ(readText(p), "original");
}

TEST(AtomicWrite, RemoveStaleTempFilesRemovesOnlyMatchingFiles) {
    fs::path dir = freshTestDir();
    for (const char* name : {".a.xml.shadowcull-tmp", ".b.shadowcull-tmp", "a.xml", "c.shadowcull-tmp",
                             ".shadowcull-tmp", ".d.shadowcull-tmp.bak", "sub/.e.shadowcull-tmp"})
        writeText(dir / name, "x");
    fs::create_directory(dir / ".f.shadowcull-tmp");  // a directory is no temporary of ours
    EXPECT_EQ(removeStaleTempFiles(dir.string()), 2);
    EXPECT_FALSE(fs::exists(dir / ".a.xml.shadowcull-tmp"));
    EXPECT_FALSE(fs::exists(dir / ".b.shadowcull-tmp"));
    for (const char* name : {"a.xml", "c.shadowcull-tmp", ".shadowcull-tmp", ".d.shadowcull-tmp.bak",
                             "sub/.e.shadowcull-tmp", ".f.shadowcull-tmp"})
        EXPECT_TRUE(fs::exists(dir / name)) << name;
    EXPECT_EQ(removeStaleTempFiles(dir.string()), 0);
    EXPECT_EQ(removeStaleTempFiles((dir / "missing").string()), 0);
}

TEST(AtomicWrite, StaleTempFromAnInterruptedWriteIsReplaced) {
    fs::path dir = freshTestDir();
    fs::path p = dir / "chunk.xml";
    writeText(tempPathFor(p.string()), "half-written garbage that is longer");
    ASSERT_TRUE(writeFileAtomic(p.string(), "whole").isOk());
    EXPECT_EQ(readText(p), "whole");
    EXPECT_FALSE(fs::exists(tempPathFor(p.string())));
}

}  // namespace
