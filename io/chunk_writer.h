// Writing <shadow> masks into chunk files: every byte outside the <shadow> elements is
// kept as it was (comments, unknown elements, attribute order, whitespace, line endings),
// and files are replaced atomically (write beside, fsync, rename).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "util/status.h"

namespace shadowcull {

// New <shadow> content for one <model> or <terrain> child of the chunk's root element.
struct ShadowWrite {
    bool write = true;                 // false: leave this element exactly as it is
    bool terrain = false;              // terrain: only the number, no RenderSet
    uint32_t mask = 0;                 // bitwise OR of groupMasks for models
    std::vector<uint32_t> groupMasks;  // models: one per primitive group, in group order
};

// Rewrites `xml` (the full text of a chunk file). `objects[i]` applies to the i-th child
// of the root element whose name is "model" or "terrain", in document order; the count
// must match exactly, else BadInput. In each such element, the first <shadow> child is
// replaced in place and any further <shadow> children are removed (with the whitespace
// before them); with none, a new <shadow> is inserted before the element's end tag, on
// its own line, indented like its siblings, using the file's line ending (CRLF or LF).
// Layout written (masks in decimal):
//   <shadow> 3
//     <RenderSet>
//       <Geometry>
//         <PrimitiveGroup> 2 </PrimitiveGroup>
//         <PrimitiveGroup> 3 </PrimitiveGroup>
//       </Geometry>
//     </RenderSet>
//   </shadow>
// Terrain: `<shadow> 3 </shadow>`.
// `file` is used in messages only.
Expected<std::string> rewriteChunkShadows(const std::string& xml, const std::string& file,
                                          const std::vector<ShadowWrite>& objects);

// BadInput (file and line) unless `xml` is one well-formed element with nothing but
// comments, processing instructions and a DOCTYPE around it: a second root element or an
// end tag without its start tag is refused, as the chunk writer refuses them (every XML
// file the tool reads is checked so, not only chunk files).
Status checkXmlStructure(const std::string& xml, const std::string& file);

// Writes `contents` to `path` atomically: a temporary file in the same directory
// (named tempPathFor(path)), fsync, rename over `path`, fsync of the directory. On any
// failure the temporary is removed and `path` is untouched (ErrorKind::Io).
Status writeFileAtomic(const std::string& path, const std::string& contents);

// The two halves of writeFileAtomic, for a bake that stages every file before replacing
// any: stageFile writes `contents` completely to tempPathFor(path) (with `path`'s
// permission bits and, where it differs from this process's, its owner and group; synced)
// and returns that name; commitStagedFile renames it over `path` and syncs the directory
// (on failure the staged file is removed, `path` untouched). With `keepOwner`, an owner or
// group that cannot be kept is an Io error; without, the replacement is this user's.
//
// For many files at once (a bake's chunk files), the syncs can be batched: stage each with
// `Sync::Later`, make them durable together with syncFileSystems (one syncfs per file
// system instead of an fsync per file), rename each with `Sync::Later`, then syncDirectories
// once. The guarantee is the same: no target is replaced before every staged byte is on
// disk, and a crash leaves each target either as it was or wholly the new text.
enum class Sync { Now, Later };
Expected<std::string> stageFile(const std::string& path, const std::string& contents, bool keepOwner = true,
                                Sync sync = Sync::Now);
Status commitStagedFile(const std::string& staged, const std::string& path, Sync syncDirectory = Sync::Now);
// Makes every file written so far on the file systems holding `paths` durable (syncfs, once
// per file system); Io error naming the path when the kernel reports a failed writeback.
Status syncFileSystems(const std::vector<std::string>& paths);
// fsync of each distinct directory holding one of `paths` (the renames into it durable).
Status syncDirectories(const std::vector<std::string>& paths);

// stageFile in pieces, for an output too large to hold (bake --results streams one chunk
// at a time): the same temporary, permissions and owner. Not thread-safe.
class StagedFile {
public:
    StagedFile() = default;
    ~StagedFile() { discard(); }
    StagedFile(StagedFile&& o) noexcept { *this = std::move(o); }
    StagedFile& operator=(StagedFile&& o) noexcept;
    StagedFile(const StagedFile&) = delete;
    StagedFile& operator=(const StagedFile&) = delete;

    static Expected<StagedFile> open(const std::string& path, bool keepOwner = true);
    bool isOpen() const { return fd_ >= 0; }
    Status append(const std::string& bytes);
    // Bytes written so far (the end of the file).
    uint64_t size() const { return size_; }
    // Cuts the file back to its first `size` bytes (a part written again).
    Status truncate(uint64_t size);
    // Everything written is on disk (fsync): a crash after this leaves the whole file.
    Status sync();
    // Closes it and renames it over the path (commitStagedFile; sync() first).
    Status commit();
    // Closes and removes the temporary (nothing happens once committed).
    void discard();
    // Closes it and leaves the temporary for the caller (stageFile).
    Status closeKeeping();

private:
    std::string path_, temp_;
    int fd_ = -1;
    uint64_t size_ = 0;
};

// Where writing `path` must go: a symbolic link (or a chain of them) is followed to the
// file it names, so that the link stays a link and its target gets the new bytes (staged
// beside the target and renamed over it). Any other path is returned as it is.
std::string writeTargetFor(const std::string& path);

// Why an existing file must not be replaced unless the user asks for it (bake
// --force-write): it is read-only (no write permission bit at all, as version control
// leaves files that are not checked out, or this user may not write it), or its owner or
// group could not be kept on the replacement. Empty when it may be replaced or does not
// exist.
std::string replaceRefusal(const std::string& path);

// The temporary name used by writeFileAtomic: ".<name>.shadowcull-tmp" beside `path`.
std::string tempPathFor(const std::string& path);

// Temporaries left in `dir` by an interrupted bake: regular files matching
// ".*.shadowcull-tmp", full paths, sorted.
std::vector<std::string> staleTempFiles(const std::string& dir);

// Removes those temporaries. Returns how many were removed.
int removeStaleTempFiles(const std::string& dir);

}  // namespace shadowcull
