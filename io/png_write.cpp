#include "io/png_write.h"

#include <cerrno>
#include <csetjmp>
#include <cstdio>

#include <png.h>

#include "io/file_read.h"

namespace shadowcull {

namespace {

thread_local std::vector<std::string> warnings;

// Handlers in place of libpng's, which would print on stderr: the error is kept for the
// message and ends in a longjmp back to writeRgbPng (libpng's contract for error handlers).
struct PngMessages {
    std::string error;
    [[noreturn]] static void onError(png_structp png, png_const_charp what) {
        static_cast<PngMessages*>(png_get_error_ptr(png))->error = what ? what : "unknown libpng error";
        png_longjmp(png, 1);
    }
    static void onWarning(png_structp, png_const_charp what) { warnings.push_back(what ? what : ""); }
};

}  // namespace

std::string libpngVersion() { return png_get_libpng_ver(nullptr); }

const std::vector<std::string>& lastPngWarnings() { return warnings; }

Status writeRgbPng(const std::string& path, int width, int height, const std::vector<unsigned char>& rgbTopDown) {
    warnings.clear();
    if (width < 1 || height < 1 || rgbTopDown.size() < size_t(width) * size_t(height) * 3)
        return makeError(ErrorKind::Internal, path, 0,
                         "picture of " + std::to_string(width) + " x " + std::to_string(height) +
                             " pixels has no pixel data to write; nothing written");
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return makeError(ErrorKind::Io, path, 0, "cannot write the picture: " + errnoText(errno));
    PngMessages messages;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &messages, &PngMessages::onError, &PngMessages::onWarning);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    auto fail = [&](const std::string& why) -> Status {
        png_destroy_write_struct(&png, &info);
        std::fclose(f);
        std::remove(path.c_str());
        return makeError(ErrorKind::Io, path, 0, why + "; no picture written");
    };
    if (!png || !info) return fail("libpng could not start (out of memory?)");
    // Everything with a destructor is made before this point: the longjmp skips none.
    if (setjmp(png_jmpbuf(png))) return fail("cannot encode the picture as PNG (libpng: " + messages.error + ")");
    png_init_io(png, f);
    png_set_IHDR(png, info, png_uint_32(width), png_uint_32(height), 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < height; ++y)
        png_write_row(png, const_cast<png_bytep>(&rgbTopDown[size_t(y) * size_t(width) * 3]));
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    if (std::fflush(f) != 0 || std::ferror(f)) {
        const int err = errno;
        std::fclose(f);
        std::remove(path.c_str());
        return makeError(ErrorKind::Io, path, 0, "cannot write the picture: " + errnoText(err) + "; no picture written");
    }
    if (std::fclose(f) != 0) {
        const int err = errno;
        std::remove(path.c_str());
        return makeError(ErrorKind::Io, path, 0, "cannot write the picture: " + errnoText(err) + "; no picture written");
    }
    return Status::ok();
}

}  // namespace shadowcull
