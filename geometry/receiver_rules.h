// The geometry stage's receivers: receiver triangles placed in the window and the receiver
// rules (semantics.md: facing, range and cone, the terrain rule), evaluated once per
// receiver and light and shared by the stage's threads.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "core/window.h"
#include "geometry/exact_frustum.h"
#include "util/thread_arena.h"

namespace shadowcull::geometry {

// A receiver triangle as the rules and the exact test see it.
struct Receiver {
    Triangle tri;  // window-local
    Aabb box;
    bool twoSided = false, mirrored = false, terrain = false;
};

// The triangle's box (exact: its vertices' extremes).
inline Aabb triangleBox(const Triangle& t) {
    Aabb b;
    for (const glm::dvec3& p : t) b.extend(p);
    return b;
}

// True when every point of the box lies deeper than the tolerance under the terrain
// (conservative: the box's top against the lowest terrain sample around it).
bool underTerrain(const BakeWindow& w, const std::array<glm::dvec3, 2>& box, double margin);

// Entries per receiver triangle (object, triangle) of a window, each made on first touch,
// in the window's arena (freed with it, at once). Two levels: a dense mesh's queries touch
// a few of its 100k+ triangles, and a table of them all, made per object, window and
// light, would cost more than the queries. Safe to use from several threads. `Entry`:
// trivially destructible, its initial state from its default member initialisers.
template <class Entry>
class TriangleTable {
public:
    TriangleTable(const BakeWindow& w, ThreadArena& arena) : w_(w), arena_(arena), tables_(w.objects.size()) {
        for (auto& t : tables_) t.store(nullptr, std::memory_order_relaxed);
    }
    TriangleTable(const TriangleTable&) = delete;
    TriangleTable& operator=(const TriangleTable&) = delete;

    // The entry, made (with its block) when missing.
    Entry& at(uint32_t object, uint32_t triangle) const {
        std::atomic<Block*>* table = tables_[object].load(std::memory_order_acquire);
        if (!table) {
            auto* fresh = arena_.make<std::atomic<Block*>>(blockCount(object));
            // Else another thread's table won (`table` now holds it); ours stays unused in the arena.
            if (tables_[object].compare_exchange_strong(table, fresh, std::memory_order_acq_rel)) table = fresh;
        }
        std::atomic<Block*>& slot = table[triangle / kBlock];
        Block* block = slot.load(std::memory_order_acquire);
        if (!block) {
            auto* fresh = arena_.make<Block>();
            if (slot.compare_exchange_strong(block, fresh, std::memory_order_acq_rel)) block = fresh;
        }
        return block->entries[triangle % kBlock];
    }

    // The entry, or null when it was never made (reads only).
    const Entry* find(uint32_t object, uint32_t triangle) const {
        const std::atomic<Block*>* table = tables_[object].load(std::memory_order_acquire);
        if (!table) return nullptr;
        const Block* block = table[triangle / kBlock].load(std::memory_order_acquire);
        return block ? &block->entries[triangle % kBlock] : nullptr;
    }

private:
    static constexpr size_t kBlock = 64;  // triangles per block of the table
    struct Block {
        Entry entries[kBlock];
    };
    size_t blockCount(size_t object) const { return (w_.objects[object].mesh->triangles.size() + kBlock - 1) / kBlock; }

    const BakeWindow& w_;
    ThreadArena& arena_;
    mutable std::vector<std::atomic<std::atomic<Block*>*>> tables_;
};

// A receiver's part above the ground (partAboveGround): points whose convex hull holds
// every point of the receiver the terrain rule lets receive. In the window's arena.
struct GroundPart {
    const glm::dvec3* points = nullptr;
    size_t count = 0;
    const glm::dvec3* data() const { return points; }
    size_t size() const { return count; }
};

// The terrain rule per receiver triangle, computed on first use and shared by every light
// (it depends on the receiver alone; a window under a low and a high sun met each buried
// receiver twice): whether the receiver lies wholly deeper than the tolerance under the
// ground, and else, with `bound`, its part above the ground (partAboveGround). Safe to call
// from several threads: an answer is computed again at worst, always the same.
class ReceiverGround {
public:
    // `bound`: also compute the part above the ground (off for the exhaustive reference,
    // which uses no double filter beyond the lowest ground under a receiver's box).
    // Parts and tables live in `arena` (outlives the answers).
    ReceiverGround(const BakeWindow& w, double margin, bool bound, ThreadArena& arena)
        : w_(w), margin_(margin), bound_(bound), arena_(arena), table_(w, arena) {}

    struct Answer {
        bool buried = false;              // the rule excludes the receiver
        const GroundPart* part = nullptr;  // its part above the ground; nullptr: no bound
    };
    // Receiver `r` is triangle (object, triangle), not itself terrain; the window has terrain.
    Answer of(uint32_t object, uint32_t triangle, const Receiver& r) const;

private:
    static constexpr uint8_t kUnknown = 0, kBuried = 1, kAbove = 2;
    struct Entry {
        std::atomic<uint8_t> state{kUnknown};
        std::atomic<const GroundPart*> part{nullptr};  // in the arena; set before state
    };

    const BakeWindow& w_;
    double margin_;
    bool bound_;
    ThreadArena& arena_;
    TriangleTable<Entry> table_;
};

// Per receiver triangle (object, triangle) and light, computed on first use (most
// receivers of a window are never tested; an object's table is made when a query first
// reaches it): -1 when the receiver rules exclude it, else a lower bound of the bias
// (metres) that applies to it; and where the terrain rule applies, the receiver's part
// above the ground (from `ground`, shared by the lights: once per receiver, not per caster
// triangle or light). Safe to call from several threads: a value is computed again at
// worst, always the same.
class ReceiverRules {
public:
    // `ground`: the window's terrain rule; `arena`: where the tables live (both outlive the rules).
    ReceiverRules(const BakeWindow& w, const Light& L, const LightGeometry& lg, const ReceiverGround& ground,
                  ThreadArena& arena)
        : w_(w), L_(L), lg_(lg), ground_(ground), table_(w, arena) {}
    ReceiverRules(const ReceiverRules&) = delete;
    ReceiverRules& operator=(const ReceiverRules&) = delete;

    // `receiver()` makes the receiver when the value is not known yet. `above`, when given,
    // receives the receiver's part above the ground (nullptr: the terrain rule gives no
    // bound there; check it only when the result is >= 0).
    template <class Make>
    double beta(uint32_t object, uint32_t triangle, const Make& receiver, const GroundPart** above = nullptr) const {
        Entry& e = table_.at(object, triangle);
        double b = e.beta.load(std::memory_order_acquire);  // after the part it publishes
        if (b == kUnknown || b == kFacesLight) {
            // Facing, range and cone already passed: the terrain rule and the bias only.
            b = b == kFacesLight ? computeRest(object, triangle, receiver(), e)
                                 : compute(object, triangle, receiver(), e);
            e.beta.store(b, std::memory_order_release);
        }
        if (above) *above = e.part.load(std::memory_order_acquire);
        return b;
    }

    // True when the cheap rules exclude the receiver: facing, range and cone (no terrain,
    // no clipping). Evaluated once per receiver and kept, as beta is (which then evaluates
    // only the rest): a rock's back faces, met by the columns of its own front faces, are
    // dismissed before any filter is placed against them. `receiver()` as for beta.
    template <class Make>
    bool excludedByFacing(uint32_t object, uint32_t triangle, const Make& receiver) const {
        Entry& e = table_.at(object, triangle);
        double b = e.beta.load(std::memory_order_acquire);
        if (b == kUnknown) {
            const double first = facesAway(receiver()) ? kExcluded : kFacesLight;
            // Unless another thread stored a value meanwhile (the same answer, or a whole one).
            if (e.beta.compare_exchange_strong(b, first, std::memory_order_acq_rel)) b = first;
        }
        return b == kExcluded;
    }

    // True when an earlier question settled that the rules exclude the receiver (beta -1,
    // or excludedByFacing true); false when they let it through or nothing was asked yet.
    // Reads only: the broad phase asks it of every leaf triangle before its box test.
    bool knownExcluded(uint32_t object, uint32_t triangle) const {
        const Entry* e = table_.find(object, triangle);
        return e && e->beta.load(std::memory_order_acquire) == kExcluded;
    }

private:
    static constexpr double kUnknown = -2.0;  // every computed value is -1 or >= 0
    static constexpr double kExcluded = -1.0;
    static constexpr double kFacesLight = -3.0;  // facing, range and cone passed; the rest not evaluated
    struct Entry {
        std::atomic<double> beta{kUnknown};
        std::atomic<const GroundPart*> part{nullptr};  // ReceiverGround's; set before beta
    };

    // -1 when the rules exclude the receiver, else its bias; publishes the part above the
    // ground in `e` (before the caller publishes the value).
    double compute(uint32_t object, uint32_t triangle, const Receiver& r, Entry& e) const {
        return facesAway(r) ? kExcluded : computeRest(object, triangle, r, e);
    }
    // The facing, range and cone rules: true when they exclude the receiver.
    bool facesAway(const Receiver& r) const;
    // compute for a receiver the facing, range and cone rules let through: the terrain rule and the bias.
    double computeRest(uint32_t object, uint32_t triangle, const Receiver& r, Entry& e) const;
    // The bias, and for directional lights the slope term (constant over a triangle).
    double bias(const Receiver& r) const;

    const BakeWindow& w_;
    const Light& L_;
    LightGeometry lg_;
    const ReceiverGround& ground_;
    TriangleTable<Entry> table_;
};

}  // namespace shadowcull::geometry
