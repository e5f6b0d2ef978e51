// Fuzz target: the bake into an output directory (bake --out) over a space whose files are
// symbolic links, duplicates or directories, and an output directory that already holds
// links (issue 35: nothing outside the output is written). Input, split by kFuzzSeparator
// (fuzz_support.h): the bake target's six files (space.xml, 00000000o.chunk,
// 00010000o.chunk, m.obj, t.terrain, t.png), then a layout program: one step per byte
// (byte mod 10):
//   0 00000000o.chunk a link to 00010000o.chunk (a duplicated input)
//   1 m.obj a link to a copy outside the space
//   2 a dangling link 00020000o.chunk
//   3 a link loop 00030000o.chunk -> itself
//   4 a directory 00040000o.chunk
//   5 OUT/00000000o.chunk a link to the space's chunk (a copy made with cp -as)
//   6 OUT/.00010000o.chunk.shadowcull-tmp a link to the outside file (a stale temporary)
//   7 OUT/.shadowcull-bake.lock a link to the outside file
//   8 the results file a link to the outside file
//   9 a duplicated chunk: 00050000o.chunk a copy of 00000000o.chunk (the same uuids twice)
// Whatever the bake answers, every file outside OUT (the space's, and the one outside it:
// every link above points into one of the two) keeps its bytes and every link of the space
// its target; otherwise the target aborts. (Links in OUT and the results path may be
// replaced or removed: they are the output's names, not what they point to.)

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "cli/pipeline.h"
#include "fuzz/fuzz_support.h"

namespace fs = std::filesystem;

namespace {

// Every entry under `dir` (not following links): a file's bytes, a link's target, or "dir".
std::map<std::string, std::string> snapshot(const fs::path& dir) {
    std::map<std::string, std::string> out;
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        const fs::path& p = it->path();
        const fs::file_status s = fs::symlink_status(p, ec);
        if (fs::is_symlink(s)) out[p.string()] = "link:" + fs::read_symlink(p, ec).string();
        else if (fs::is_directory(s)) out[p.string()] = "dir";
        else {
            std::ifstream in(p, std::ios::binary);
            std::ostringstream bytes;
            bytes << in.rdbuf();
            out[p.string()] = "file:" + bytes.str();
        }
    }
    return out;
}

void link(const fs::path& target, const fs::path& at) {
    std::error_code ec;
    fs::remove(at, ec);
    fs::create_symlink(target, at, ec);
}

void applyLayout(const std::string& program, const fs::path& space, const fs::path& outside, const fs::path& out,
                 const fs::path& results) {
    std::error_code ec;
    for (unsigned char step : program.substr(0, 16)) {
        switch (step % 10) {
            case 0: link("00010000o.chunk", space / "00000000o.chunk"); break;
            case 1:
                fs::copy_file(space / "m.obj", outside / "m.obj", fs::copy_options::overwrite_existing, ec);
                link(outside / "m.obj", space / "m.obj");
                break;
            case 2: link(space / "missing.chunk", space / "00020000o.chunk"); break;
            case 3: link("00030000o.chunk", space / "00030000o.chunk"); break;
            case 4: fs::create_directories(space / "00040000o.chunk", ec); break;
            case 5: link(fs::absolute(space / "00000000o.chunk"), out / "00000000o.chunk"); break;
            case 6: link(outside / "secret", out / ".00010000o.chunk.shadowcull-tmp"); break;
            case 7: link(outside / "secret", out / ".shadowcull-bake.lock"); break;
            case 8: link(outside / "secret", results); break;
            case 9: fs::copy_file(space / "00000000o.chunk", space / "00050000o.chunk", fs::copy_options::overwrite_existing, ec); break;
        }
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> parts = splitInput(data, size, 7);
    const std::string program = parts.size() == 7 ? parts[6] : std::string();
    parts.resize(std::min<size_t>(parts.size(), 6));
    if (parts.size() == 6) parts[5] = withPngCrcsFixed(std::move(parts[5]));
    const fs::path root = scratchDir(), space = root / "space", outside = root / "outside", out = root / "out",
                   results = root / "results.json";
    std::error_code ec;
    for (const fs::path& p : {space, outside, out}) {
        fs::remove_all(p, ec);
        fs::create_directories(p, ec);
    }
    fs::remove(results, ec);
    writeFiles(parts, {"space/space.xml", "space/00000000o.chunk", "space/00010000o.chunk", "space/m.obj", "space/t.terrain",
                       "space/t.png"});
    std::ofstream(outside / "secret") << "not the bake's to write\n";
    applyLayout(program, space, outside, out, results);
    const std::map<std::string, std::string> spaceBefore = snapshot(space), outsideBefore = snapshot(outside);

    shadowcull::cli::BakeOptions opt;
    opt.spaceDir = space.string();
    opt.outDir = out.string();
    opt.resultsPath = results.string();
    opt.threads = 1;
    opt.useGpu = false;
    // Few samples: a run must stay fast; what is sought does not depend on their number.
    opt.raycast.areaSamples = 8;
    opt.raycast.maxFeatureSamples = 32;
    opt.raycast.threads = 1;
    (void)shadowcull::cli::runBake(opt);

    if (snapshot(space) != spaceBefore) brokenPromise("the bake changed a file of the space (it writes into --out only)");
    if (snapshot(outside) != outsideBefore) brokenPromise("the bake wrote a file outside the space and the output");
    return 0;
}
