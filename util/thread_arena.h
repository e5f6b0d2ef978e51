// Memory for many small objects made by several threads and freed all at once: each
// thread bumps through chunks of its own, and the arena frees the chunks when it goes.
// The geometry stage's per-window tables (hundreds of thousands of 1 KiB blocks and
// receiver parts over a bake, each freed alone, took a tenth of the stage in malloc and
// free, the frees serial after the window's tasks). Objects placed here are never
// destroyed: only trivially destructible types belong in it.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>
#include <vector>

#include <tbb/enumerable_thread_specific.h>

namespace shadowcull {

class ThreadArena {
public:
    explicit ThreadArena(size_t chunkBytes = size_t(256) << 10) : chunkBytes_(chunkBytes) {}
    ThreadArena(const ThreadArena&) = delete;
    ThreadArena& operator=(const ThreadArena&) = delete;

    // Uninitialised room for `bytes` bytes aligned to `align` (a power of two, at most
    // alignof(std::max_align_t)), valid until the arena is destroyed. Safe from several threads.
    void* allocate(size_t bytes, size_t align) {
        Local& local = locals_.local();
        size_t pad = (align - reinterpret_cast<uintptr_t>(local.next) % align) % align;
        if (!local.next || pad + bytes > local.left) {
            const size_t size = std::max(chunkBytes_, bytes);
            const size_t units = (size + sizeof(std::max_align_t) - 1) / sizeof(std::max_align_t);
            local.chunks.emplace_back(new std::max_align_t[units]);
            local.next = reinterpret_cast<std::byte*>(local.chunks.back().get());
            local.left = size;
            pad = 0;
        }
        std::byte* p = local.next + pad;
        local.next = p + bytes;
        local.left -= pad + bytes;
        return p;
    }

    // `count` value-initialised objects of T (trivially destructible: never destroyed).
    template <class T>
    T* make(size_t count = 1) {
        static_assert(std::is_trivially_destructible_v<T>, "the arena never destroys what it holds");
        static_assert(alignof(T) <= alignof(std::max_align_t));
        T* p = static_cast<T*>(allocate(count * sizeof(T), alignof(T)));
        for (size_t i = 0; i < count; ++i) new (p + i) T();
        return p;
    }

private:
    struct Local {
        std::vector<std::unique_ptr<std::max_align_t[]>> chunks;
        std::byte* next = nullptr;
        size_t left = 0;
    };
    size_t chunkBytes_;
    tbb::enumerable_thread_specific<Local> locals_;
};

}  // namespace shadowcull
