// Byte-preserving <shadow> writer. Chunk files are edited as text: a small XML scanner
// finds the byte spans of elements, and only the spans of <shadow> elements (or an
// insertion point) change. A DOM round trip (tinyxml2) would re-serialise the whole file
// and lose comments' layout, quoting, CRLF endings and the like, which users diff.

#include "io/chunk_writer.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

#include "util/stop_request.h"

namespace shadowcull {

namespace {

// One element of the document, as byte offsets into the text.
struct Node {
    std::string name;
    size_t begin = 0;     // '<' of the start tag
    size_t tagEnd = 0;    // one past the '>' of the start tag
    size_t endBegin = 0;  // '<' of the end tag (== tagEnd when self-closing)
    size_t end = 0;       // one past the '>' of the end tag (== tagEnd when self-closing)
    bool selfClosing = false;
    std::vector<size_t> children;  // indices of direct child elements, in document order
};

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

// XML names are stricter, but anything that cannot end a name is enough to find spans.
bool isNameChar(char c) { return !isSpace(c) && c != '/' && c != '>' && c != '<' && c != '=' && c != '"' && c != '\''; }

bool startsWith(const std::string& s, size_t at, const char* prefix) { return s.compare(at, std::strlen(prefix), prefix) == 0; }

int lineAt(const std::string& s, size_t pos) {
    return 1 + int(std::count(s.begin(), s.begin() + std::min(pos, s.size()), '\n'));
}

size_t lineStart(const std::string& s, size_t pos) {
    size_t nl = pos == 0 ? std::string::npos : s.rfind('\n', pos - 1);
    return nl == std::string::npos ? 0 : nl + 1;
}

// True when only spaces and tabs precede `pos` on its line.
bool beginsLine(const std::string& s, size_t pos) {
    for (size_t p = lineStart(s, pos); p < pos; ++p)
        if (s[p] != ' ' && s[p] != '\t') return false;
    return true;
}

// The leading spaces and tabs of the line that contains `pos`.
std::string lineIndent(const std::string& s, size_t pos) {
    size_t b = lineStart(s, pos), e = b;
    while (e < s.size() && (s[e] == ' ' || s[e] == '\t')) ++e;
    return s.substr(b, e - b);
}

size_t skipSpace(const std::string& s, size_t p) {
    while (p < s.size() && isSpace(s[p])) ++p;
    return p;
}

size_t skipName(const std::string& s, size_t p) {
    while (p < s.size() && isNameChar(s[p])) ++p;
    return p;
}

// The index of the last character of the first `close` at or after `from`, or npos.
size_t lastCharOf(const std::string& s, size_t from, const std::string& close) {
    size_t e = s.find(close, from);
    return e == std::string::npos ? e : e + close.size() - 1;
}

// Scans the whole document. Returns all elements in document order; nodes[0] is the root.
Expected<std::vector<Node>> scanXml(const std::string& s, const std::string& file) {
    auto fail = [&](size_t at, const std::string& msg) {
        return makeError(ErrorKind::BadInput, file, lineAt(s, at), msg);
    };
    std::vector<Node> nodes;
    std::vector<size_t> open;  // unclosed elements, innermost last
    bool rootClosed = false;
    size_t i = startsWith(s, 0, "\xEF\xBB\xBF") ? 3 : 0;
    while (i < s.size()) {
        if (s[i] != '<') {
            size_t next = std::min(s.find('<', i), s.size());
            size_t text = s.find_first_not_of(" \t\r\n", i);
            if (open.empty() && text < next)
                return fail(text, rootClosed ? "text after the root element" : "text before the root element");
            i = next;
            continue;
        }
        // Markup whose content may hold '<' and '>' is skipped whole.
        auto skipTo = [&](size_t from, const char* close, const char* what) -> Status {
            size_t e = s.find(close, from);
            if (e == std::string::npos) return fail(i, std::string("unclosed ") + what);
            i = e + std::strlen(close);
            return Status::ok();
        };
        if (startsWith(s, i, "<!--")) {
            if (Status st = skipTo(i + 4, "-->", "comment"); !st) return st.error();
        } else if (startsWith(s, i, "<![CDATA[")) {
            if (open.empty()) return fail(i, "CDATA outside the root element");
            if (Status st = skipTo(i + 9, "]]>", "CDATA section"); !st) return st.error();
        } else if (startsWith(s, i, "<?")) {
            if (Status st = skipTo(i + 2, "?>", "processing instruction"); !st) return st.error();
        } else if (startsWith(s, i, "<!DOCTYPE")) {
            if (!nodes.empty()) return fail(i, "DOCTYPE inside or after the root element");
            // The internal subset [...] may hold '>' in declarations, quoted literals and comments.
            size_t p = i + 9;
            for (int depth = 0; p < s.size(); ++p) {
                if (s[p] == '"' || s[p] == '\'') p = lastCharOf(s, p + 1, std::string(1, s[p]));
                else if (startsWith(s, p, "<!--")) p = lastCharOf(s, p + 4, "-->");
                else if (startsWith(s, p, "<?")) p = lastCharOf(s, p + 2, "?>");
                else if (s[p] == '[') ++depth;
                else if (s[p] == ']') --depth;
                else if (s[p] == '>' && depth <= 0) break;
                if (p == std::string::npos) break;  // unclosed literal, comment or PI
            }
            if (p >= s.size()) return fail(i, "unclosed DOCTYPE");
            i = p + 1;
        } else if (startsWith(s, i, "</")) {
            size_t n = skipName(s, i + 2), p = skipSpace(s, n);
            std::string name = s.substr(i + 2, n - i - 2);
            if (name.empty() || p >= s.size() || s[p] != '>') return fail(i, "malformed end tag");
            if (open.empty()) return fail(i, "end tag </" + name + "> without a start tag");
            Node& top = nodes[open.back()];
            if (top.name != name)
                return fail(i, "end tag </" + name + "> does not match <" + top.name + "> from line " +
                                   std::to_string(lineAt(s, top.begin)));
            top.endBegin = i;
            top.end = p + 1;
            open.pop_back();
            rootClosed = open.empty();
            i = p + 1;
        } else if (startsWith(s, i, "<!")) {
            return fail(i, "unexpected markup '<!'");
        } else {
            Node node;
            node.begin = i;
            size_t n = skipName(s, i + 1);
            node.name = s.substr(i + 1, n - i - 1);
            if (node.name.empty()) return fail(i, "'<' not followed by an element name");
            if (open.empty() && !nodes.empty()) return fail(i, "second root element <" + node.name + ">");
            size_t p = n;
            for (;;) {
                p = skipSpace(s, p);
                if (p >= s.size()) return fail(i, "unclosed start tag <" + node.name + ">");
                if (s[p] == '>') break;
                if (startsWith(s, p, "/>")) {
                    node.selfClosing = true;
                    ++p;
                    break;
                }
                size_t a = p;
                p = skipSpace(s, skipName(s, p));
                if (p == a || p >= s.size() || s[p] != '=')
                    return fail(std::min(p, s.size() - 1), "malformed attribute in <" + node.name + ">");
                p = skipSpace(s, p + 1);
                if (p >= s.size() || (s[p] != '"' && s[p] != '\''))
                    return fail(std::min(p, s.size() - 1), "unquoted attribute value in <" + node.name + ">");
                size_t q = s.find(s[p], p + 1);
                if (q == std::string::npos) return fail(p, "unclosed attribute value in <" + node.name + ">");
                p = q + 1;
            }
            node.tagEnd = p + 1;
            if (node.selfClosing) node.endBegin = node.end = node.tagEnd;
            size_t index = nodes.size();
            if (!open.empty()) nodes[open.back()].children.push_back(index);
            nodes.push_back(std::move(node));
            if (!nodes.back().selfClosing) open.push_back(index);
            rootClosed = open.empty();
            i = p + 1;
        }
    }
    if (!open.empty()) return fail(nodes[open.back()].begin, "<" + nodes[open.back()].name + "> is never closed");
    if (nodes.empty()) return fail(s.empty() ? 0 : s.size() - 1, "no root element");
    return nodes;
}

// The file's own conventions, so inserted text looks like its neighbours.
std::string detectLineEnding(const std::string& s) {
    size_t nl = s.find('\n');
    return nl != std::string::npos && nl > 0 && s[nl - 1] == '\r' ? "\r\n" : "\n";
}

std::string detectIndentUnit(const std::string& s) {
    for (size_t p = 0; p < s.size();) {
        size_t q = std::min(s.find('\n', p), s.size());
        if ((s[p] == ' ' || s[p] == '\t') && s.find_first_not_of(" \t\r", p) < q) return s[p] == '\t' ? "\t" : "  ";
        p = q + 1;
    }
    return "  ";
}

struct Layout {
    std::string eol, unit;
};

// The <shadow> element text. `inlineForm` writes it on one line (for elements that sit on
// one line); otherwise nested lines are indented from `indent`, the <shadow> line's indentation.
std::string shadowText(const ShadowWrite& w, const std::string& indent, const Layout& layout, bool inlineForm) {
    std::string out = "<shadow> " + std::to_string(w.mask);
    if (w.terrain || w.groupMasks.empty()) return out + " </shadow>";
    auto line = [&](int depth, const std::string& text) {
        if (inlineForm) {
            out += " ";
        } else {
            out += layout.eol + indent;
            for (int d = 0; d < depth; ++d) out += layout.unit;
        }
        out += text;
    };
    line(1, "<RenderSet>");
    line(2, "<Geometry>");
    for (uint32_t g : w.groupMasks) line(3, "<PrimitiveGroup> " + std::to_string(g) + " </PrimitiveGroup>");
    line(2, "</Geometry>");
    line(1, "</RenderSet>");
    line(0, "</shadow>");
    return out;
}

struct Edit {
    size_t begin, end;  // the replaced span
    std::string text;
};

// The edits for one <model> or <terrain> element.
void planElement(const std::string& s, const std::vector<Node>& nodes, const Node& el, const ShadowWrite& w,
                 const Layout& layout, std::vector<Edit>& edits) {
    // An element written on one line stays on one line; the choice depends only on the
    // element's own shape so that a second rewrite reproduces the first (idempotence).
    bool inlineForm = el.selfClosing ? !beginsLine(s, el.begin)
                                     : s.find('\n', el.begin) >= el.endBegin;
    std::vector<const Node*> shadows;
    for (size_t c : el.children)
        if (nodes[c].name == "shadow") shadows.push_back(&nodes[c]);

    if (!shadows.empty()) {
        const Node& first = *shadows[0];
        edits.push_back({first.begin, first.end, shadowText(w, lineIndent(s, first.begin), layout, inlineForm)});
        for (size_t k = 1; k < shadows.size(); ++k) {
            // Take the indentation and, for a shadow alone at its line start, the line break
            // before it, so no blank line is left where it was.
            size_t b = shadows[k]->begin;
            while (b > 0 && (s[b - 1] == ' ' || s[b - 1] == '\t')) --b;
            if (b > 0 && s[b - 1] == '\n') {
                --b;
                if (b > 0 && s[b - 1] == '\r') --b;
            }
            edits.push_back({b, shadows[k]->end, ""});
        }
        return;
    }

    std::string indent = lineIndent(s, el.begin);
    std::string endTag = "</" + el.name + ">";
    if (el.selfClosing) {
        // <model a="1"/> -> <model a="1"> ... </model>; whitespace before "/>" goes too.
        size_t b = el.tagEnd - 2;
        while (isSpace(s[b - 1])) --b;
        std::string text = inlineForm ? "> " + shadowText(w, indent, layout, true) + " " + endTag
                                      : ">" + layout.eol + indent + layout.unit +
                                            shadowText(w, indent + layout.unit, layout, false) + layout.eol +
                                            indent + endTag;
        edits.push_back({b, el.tagEnd, text});
    } else if (inlineForm) {
        std::string lead = isSpace(s[el.endBegin - 1]) ? "" : " ";
        edits.push_back({el.endBegin, el.endBegin, lead + shadowText(w, indent, layout, true) + " "});
    } else {
        // Indent like the last child element when it starts its own line, else one unit in.
        std::string childIndent = indent + layout.unit;
        if (!el.children.empty() && beginsLine(s, nodes[el.children.back()].begin))
            childIndent = lineIndent(s, nodes[el.children.back()].begin);
        std::string line = childIndent + shadowText(w, childIndent, layout, false) + layout.eol;
        if (beginsLine(s, el.endBegin)) {
            size_t at = lineStart(s, el.endBegin);
            edits.push_back({at, at, line});
        } else {
            edits.push_back({el.endBegin, el.endBegin, layout.eol + line + indent});
        }
    }
}

Status ioError(const std::string& path, const std::string& what) {
    return makeError(ErrorKind::Io, path, 0, what + ": " + std::strerror(errno));
}

std::string octalMode(mode_t mode) {
    char buf[8];
    std::snprintf(buf, sizeof buf, "%04o", unsigned(mode & 07777));
    return buf;
}

std::string parentDir(const std::string& path) {
    size_t slash = path.rfind('/');
    if (slash == std::string::npos) return ".";
    return slash == 0 ? "/" : path.substr(0, slash);
}

}  // namespace

Expected<std::string> rewriteChunkShadows(const std::string& xml, const std::string& file,
                                          const std::vector<ShadowWrite>& objects) {
    Expected<std::vector<Node>> scanned = scanXml(xml, file);
    if (!scanned) return scanned.error();
    const std::vector<Node>& nodes = *scanned;
    const Node& root = nodes[0];

    std::vector<const Node*> elements;
    for (size_t c : root.children)
        if (nodes[c].name == "model" || nodes[c].name == "terrain") elements.push_back(&nodes[c]);
    if (elements.size() != objects.size())
        return makeError(ErrorKind::BadInput, file, lineAt(xml, root.begin),
                         "<" + root.name + "> has " + std::to_string(elements.size()) +
                             " <model>/<terrain> elements, but " + std::to_string(objects.size()) +
                             " objects were given (was the file changed?)");

    Layout layout{detectLineEnding(xml), detectIndentUnit(xml)};
    std::vector<Edit> edits;
    for (size_t k = 0; k < elements.size(); ++k) {
        const ShadowWrite& w = objects[k];
        if (!w.write) continue;
        // A kind mismatch means the file is not the one the objects were read from.
        if (w.terrain != (elements[k]->name == "terrain"))
            return makeError(ErrorKind::BadInput, file, lineAt(xml, elements[k]->begin),
                             "object " + std::to_string(k) + " is <" + elements[k]->name + "> here but was read as " +
                                 (w.terrain ? "terrain" : "a model"));
        planElement(xml, nodes, *elements[k], w, layout, edits);
    }

    std::stable_sort(edits.begin(), edits.end(), [](const Edit& a, const Edit& b) { return a.begin < b.begin; });
    std::string out;
    out.reserve(xml.size() + 256 * edits.size());
    size_t at = 0;
    for (const Edit& e : edits) {
        out.append(xml, at, e.begin - at);
        out += e.text;
        at = e.end;
    }
    out.append(xml, at, std::string::npos);
    return out;
}

Status checkXmlStructure(const std::string& xml, const std::string& file) {
    Expected<std::vector<Node>> scanned = scanXml(xml, file);
    return scanned ? Status::ok() : Status(scanned.error());
}

std::string tempPathFor(const std::string& path) {
    size_t slash = path.rfind('/');
    size_t nameAt = slash == std::string::npos ? 0 : slash + 1;
    return path.substr(0, nameAt) + "." + path.substr(nameAt) + ".shadowcull-tmp";
}

std::string writeTargetFor(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::is_symlink(path, ec)) return path;
    const std::filesystem::path target = std::filesystem::weakly_canonical(path, ec);
    return ec ? path : target.string();
}

std::string replaceRefusal(const std::string& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return {};
    if ((st.st_mode & 0222) == 0) return "read-only (mode " + octalMode(st.st_mode) + ")";
    if (::access(path.c_str(), W_OK) != 0) return "not writable by this user";
    if (::geteuid() != 0) {
        // Only root may give a file away; a member of the file's group may keep the group.
        if (st.st_uid != ::geteuid()) return "owned by another user (uid " + std::to_string(st.st_uid) + "), who would lose it";
        if (st.st_gid != ::getegid()) {
            std::vector<gid_t> groups(size_t(std::max(0, ::getgroups(0, nullptr))));
            const int n = ::getgroups(int(groups.size()), groups.data());
            if (std::find(groups.begin(), groups.begin() + std::max(0, n), st.st_gid) == groups.begin() + std::max(0, n))
                return "of group " + std::to_string(st.st_gid) + ", which this user cannot keep";
        }
    }
    return {};
}

StagedFile& StagedFile::operator=(StagedFile&& o) noexcept {
    if (this != &o) {
        discard();
        path_ = std::move(o.path_), temp_ = std::move(o.temp_);
        fd_ = o.fd_, size_ = o.size_;
        o.fd_ = -1;
    }
    return *this;
}

Expected<StagedFile> StagedFile::open(const std::string& path, bool keepOwner) {
    StagedFile f;
    f.path_ = path;
    f.temp_ = tempPathFor(path);
    // Keep the permissions users gave the file; a new file gets the umask's default.
    struct stat st {};
    bool existed = ::stat(path.c_str(), &st) == 0;
    // A new file of our own, never through a name someone left there: O_EXCL | O_NOFOLLOW,
    // and a stale temporary (a killed bake's, or a symbolic link planted in its place) is
    // unlinked first, which removes the name and never touches what a link points to.
    f.fd_ = ::open(f.temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    if (f.fd_ < 0 && errno == EEXIST && ::unlink(f.temp_.c_str()) == 0)
        f.fd_ = ::open(f.temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    if (f.fd_ < 0) return ioError(path, "cannot create temporary file " + f.temp_).error();
    auto fail = [&](const std::string& what) {
        Status s = ioError(path, what);  // before close/unlink can change errno
        f.discard();
        return s.error();
    };
    if (existed && (st.st_uid != ::geteuid() || st.st_gid != ::getegid()) && ::fchown(f.fd_, st.st_uid, st.st_gid) != 0 &&
        keepOwner)
        return fail("cannot keep the owner and group of the file on " + f.temp_);
    // After fchown, which may clear set-id bits.
    if (existed && ::fchmod(f.fd_, st.st_mode & 07777) != 0) return fail("cannot set permissions of " + f.temp_);
    return f;
}

Status StagedFile::append(const std::string& bytes) {
    for (size_t done = 0; done < bytes.size();) {
        ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) return ioError(path_, "cannot write " + temp_);
        done += size_t(n);
    }
    size_ += bytes.size();
    return Status::ok();
}

Status StagedFile::truncate(uint64_t size) {
    if (::ftruncate(fd_, off_t(size)) != 0 || ::lseek(fd_, off_t(size), SEEK_SET) < 0)
        return ioError(path_, "cannot cut back " + temp_);
    size_ = size;
    return Status::ok();
}

Status StagedFile::sync() {
    if (::fsync(fd_) != 0) return ioError(path_, "cannot sync " + temp_);
    return Status::ok();
}

Status StagedFile::commit() {
    const int closed = ::close(fd_);
    fd_ = -1;
    if (closed != 0) {
        Status s = ioError(path_, "cannot close " + temp_);
        ::unlink(temp_.c_str());
        return s;
    }
    Status s = commitStagedFile(temp_, path_);
    temp_.clear();  // renamed, or removed by commitStagedFile
    return s;
}

Status StagedFile::closeKeeping() {
    const int closed = ::close(fd_);
    fd_ = -1;
    if (closed != 0) {
        Status s = ioError(path_, "cannot close " + temp_);
        discard();
        return s;
    }
    temp_.clear();
    return Status::ok();
}

void StagedFile::discard() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    if (!temp_.empty()) ::unlink(temp_.c_str());
    temp_.clear();
}

Expected<std::string> stageFile(const std::string& path, const std::string& contents, bool keepOwner, Sync sync) {
    Expected<StagedFile> f = StagedFile::open(path, keepOwner);
    if (!f) return f.error();
    if (Status s = f->append(contents); !s) return s.error();
    if (sync == Sync::Now)
        if (Status s = f->sync(); !s) return s.error();
    // Closed and handed over: the caller commits or removes it.
    std::string temp = tempPathFor(path);
    if (Status s = f->closeKeeping(); !s) return s.error();
    return temp;
}

namespace {

// Makes the renames into `path`'s directory durable. Some file systems cannot sync
// directories (EINVAL).
Status syncDirectoryOf(const std::string& path) {
    int dfd = ::open(parentDir(path).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd < 0) return ioError(path, "file replaced, but cannot open its directory to sync it");
    int synced = ::fsync(dfd);
    Status s = synced != 0 && errno != EINVAL ? ioError(path, "file replaced, but syncing its directory failed")
                                              : Status::ok();
    ::close(dfd);
    return s;
}

}  // namespace

Status commitStagedFile(const std::string& staged, const std::string& path, Sync syncDirectory) {
    if (::rename(staged.c_str(), path.c_str()) != 0) {
        Status s = ioError(path, "cannot replace the file");
        ::unlink(staged.c_str());
        return s;
    }
    return syncDirectory == Sync::Now ? syncDirectoryOf(path) : Status::ok();
}

Status syncFileSystems(const std::vector<std::string>& paths) {
    std::vector<dev_t> done;
    for (const std::string& path : paths) {
        struct stat st {};
        if (::stat(path.c_str(), &st) != 0) return ioError(path, "cannot sync the file");
        if (std::find(done.begin(), done.end(), st.st_dev) != done.end()) continue;
        int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
        if (fd < 0) return ioError(path, "cannot open the file to sync it");
        const int synced = ::syncfs(fd);
        ::close(fd);
        if (synced != 0) return ioError(path, "syncing its file system failed");
        done.push_back(st.st_dev);
    }
    return Status::ok();
}

Status syncDirectories(const std::vector<std::string>& paths) {
    std::vector<std::string> done;
    for (const std::string& path : paths) {
        const std::string dir = parentDir(path);
        if (std::find(done.begin(), done.end(), dir) != done.end()) continue;
        if (Status s = syncDirectoryOf(path); !s) return s;
        done.push_back(dir);
    }
    return Status::ok();
}

Status writeFileAtomic(const std::string& path, const std::string& contents) {
    Expected<StagedFile> f = StagedFile::open(path);
    if (!f) return f.error();
    // Held from creation to the rename: a signal that ends the process removes it.
    const std::string temp = tempPathFor(path);
    const bool held = holdTemporary(temp.c_str());
    Status s = f->append(contents);
    if (s) s = f->sync();
    if (s) s = f->commit();
    if (held) releaseTemporary();
    return s;
}

std::vector<std::string> staleTempFiles(const std::string& dir) {
    static const std::string suffix = ".shadowcull-tmp";
    std::vector<std::string> out;
    DIR* d = ::opendir(dir.c_str());
    if (!d) return out;
    while (const dirent* e = ::readdir(d)) {
        std::string name = e->d_name;
        if (name.size() <= suffix.size() || name[0] != '.' ||
            name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
            continue;
        std::string full = dir + "/" + name;
        struct stat st {};
        if (::lstat(full.c_str(), &st) == 0 && S_ISREG(st.st_mode)) out.push_back(full);
    }
    ::closedir(d);
    std::sort(out.begin(), out.end());
    return out;
}

int removeStaleTempFiles(const std::string& dir) {
    int removed = 0;
    for (const std::string& f : staleTempFiles(dir)) removed += ::unlink(f.c_str()) == 0;
    return removed;
}

}  // namespace shadowcull
