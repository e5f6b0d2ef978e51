// The bundled sample space (data/sample/): a small village on gently hilly terrain,
// 3 x 3 chunks of 100 m (gx, gz in -1..1), with rocks, trees (opaque trunk + alpha-tested
// leaf cards), houses, a sign, a trough (open mesh), three objects whose true masks are 0,
// a comment and an unknown element to preserve, and three lights. Deterministic: a
// fixed-seed SplitMix64 and our own formulas (no std distributions), so every platform
// writes the same bytes.

#include "tests/support/sample_space.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

namespace shadowcull::testing {

namespace {

constexpr double kChunk = 100.0;  // metres

// Gentle hills: a few long sine waves, about -2 m .. +5 m. Terrain is stored between
// -10 m and +20 m (a 0.46 mm quantisation step).
double hills(double x, double z) {
    return 2.0 * std::sin(0.031 * x + 0.4) * std::cos(0.027 * z) + 1.0 * std::sin(0.055 * (x - 0.6 * z)) +
           0.6 * std::cos(0.071 * z + 0.013 * x) + 1.5;
}

// A lumpy closed solid: an octahedron subdivided `levels` times, each vertex pushed out
// to radius * [1 - jitter, 1 + jitter], then squashed in y. Scaling a vertex along its own
// ray keeps every face's orientation about the centre, so the result stays outward-facing.
MeshSpec lumpySolid(uint64_t seed, double radius, double jitter, double squash, int levels, const GroupSpec& group) {
    std::vector<glm::dvec3> v = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    std::vector<std::array<int, 3>> faces;
    for (int x : {0, 1})
        for (int y : {2, 3})
            for (int z : {4, 5}) {
                const glm::dvec3 a = v[size_t(x)], b = v[size_t(y)], c = v[size_t(z)];
                const double det = a.x * (b.y * c.z - b.z * c.y) - a.y * (b.x * c.z - b.z * c.x) +
                                   a.z * (b.x * c.y - b.y * c.x);
                faces.push_back(det > 0 ? std::array<int, 3>{x, y, z} : std::array<int, 3>{x, z, y});
            }
    for (int level = 0; level < levels; ++level) {
        std::map<std::pair<int, int>, int> middle;
        auto mid = [&](int a, int b) {
            const std::pair<int, int> key{std::min(a, b), std::max(a, b)};
            auto it = middle.find(key);
            if (it != middle.end()) return it->second;
            const glm::dvec3 m = (v[size_t(a)] + v[size_t(b)]) * 0.5;
            v.push_back(m / std::sqrt(m.x * m.x + m.y * m.y + m.z * m.z));
            return middle[key] = int(v.size()) - 1;
        };
        std::vector<std::array<int, 3>> finer;
        for (const auto& f : faces) {
            const int ab = mid(f[0], f[1]), bc = mid(f[1], f[2]), ca = mid(f[2], f[0]);
            finer.insert(finer.end(), {{f[0], ab, ca}, {ab, f[1], bc}, {ca, bc, f[2]}, {ab, bc, ca}});
        }
        faces = finer;
    }
    DeterministicRng rng(seed);
    MeshSpec m;
    const int g = m.addGroup(group);
    for (const glm::dvec3& p : v) {
        const double r = radius * rng.uniform(1.0 - jitter, 1.0 + jitter);
        m.addVertex(glm::dvec3(p.x * r, p.y * r * squash, p.z * r));
    }
    for (const auto& f : faces) m.addTriangle(f[0], f[1], f[2], g);
    return m;
}

// Trunk (opaque "bark", 3.5 m) and three crossed leaf cards (alpha-tested "leaves" via MTL
// map_d, two-sided), 4 m wide, from 2.5 m to 6.5 m.
MeshSpec treeMesh() {
    MeshSpec tree = MeshSpec::box({-0.2, 0, -0.2}, {0.2, 3.5, 0.2}, GroupSpec::named("bark"));
    MeshSpec leaves;
    const int g = leaves.addGroup(GroupSpec::named("leaves", true));
    leaves.addFace({{-2, 2.5, 0}, {2, 2.5, 0}, {2, 6.5, 0}, {-2, 6.5, 0}}, g, {0, 4.5, -1});
    leaves.addFace({{0, 2.5, -2}, {0, 2.5, 2}, {0, 6.5, 2}, {0, 6.5, -2}}, g, {-1, 4.5, 0});
    leaves.addFace({{-2, 5, -2}, {2, 5, -2}, {2, 5, 2}, {-2, 5, 2}}, g, {0, 4, 0});
    return tree.append(leaves);
}

// 8 m x 10 m house, walls 5 m high with a 1 m foundation below the origin, and a gable
// roof (ridge along z at 8 m, 0.5 m overhang) as a second group. Both closed, opaque.
MeshSpec houseMesh() {
    MeshSpec house = MeshSpec::box({-4, -1, -5}, {4, 5, 5}, GroupSpec::named("walls"));
    MeshSpec roof;
    const int g = roof.addGroup(GroupSpec::named("roof"));
    const glm::dvec3 a{-4.5, 5, -5.5}, b{4.5, 5, -5.5}, c{4.5, 5, 5.5}, d{-4.5, 5, 5.5};
    const glm::dvec3 r0{0, 8, -5.5}, r1{0, 8, 5.5}, inside{0, 6, 0};
    roof.addFace({a, b, c, d}, g, inside);
    roof.addFace({a, d, r1, r0}, g, inside);
    roof.addFace({b, r0, r1, c}, g, inside);
    roof.addFace({a, r0, b}, g, inside);
    roof.addFace({d, c, r1}, g, inside);
    return house.append(roof);
}

// A post with a board; the board is a single quad made two-sided by a .model override.
MeshSpec signMesh() {
    MeshSpec sign = MeshSpec::box({-0.05, 0, -0.05}, {0.05, 1.8, 0.05}, GroupSpec::named("wood"));
    GroupSpec paint = GroupSpec::named("paint");
    paint.doubleSidedOverride = true;
    return sign.append(MeshSpec::quad({-0.6, 1.2, 0.06}, {0.6, 1.2, 0.06}, {0.6, 1.9, 0.06}, {-0.6, 1.9, 0.06}, paint));
}

// Rounds to a millimetre (or a hundredth, a whole degree): the sample is read by people too,
// and "71.604" says as much as "71.60426272321422".
double mm(double v) { return std::round(v * 1000.0) / 1000.0; }

Affine placed(const glm::dvec3& at, double yawDegrees = 0.0, double scale = 1.0) {
    const double s = std::round(scale * 100.0) / 100.0;
    return Affine::scaling(glm::dvec3(s))
        .then(Affine::rotationY(std::round(yawDegrees)))
        .then(Affine::translation({mm(at.x), mm(at.y), mm(at.z)}));
}

// The lowest terrain point under a disc of radius r around (x, z): what to stand things on.
double groundUnder(const SpaceBuilder& b, double x, double z, double r) {
    double h = *b.terrainHeightAt(x, z);
    for (int k = 0; k < 8; ++k) {
        const double a = k * 0.25 * 3.14159265358979323846;
        h = std::min(h, *b.terrainHeightAt(x + r * std::cos(a), z + r * std::sin(a)));
    }
    return h;
}

struct Reserved {
    double x, z, radius;  // metres
};

}  // namespace

SpaceBuilder sampleSpace() {
    SpaceBuilder b;  // chunk size 100, neighbours 1, terrain tolerance 0.01
    for (int gx = -1; gx <= 1; ++gx)
        for (int gz = -1; gz <= 1; ++gz) b.addTerrain(gx, gz, 33, hills, -10.0, 20.0);

    b.addMesh("rock_a", lumpySolid(11, 1.0, 0.25, 0.7, 1, GroupSpec::named("stone")));
    b.addMesh("rock_b", lumpySolid(22, 1.0, 0.30, 0.55, 1, GroupSpec::named("stone")));
    b.addMesh("rock_c", lumpySolid(33, 1.0, 0.20, 0.9, 2, GroupSpec::named("stone")));
    b.addMesh("tree", treeMesh());
    b.addMesh("house", houseMesh());
    b.addMesh("sign", signMesh());
    b.addMesh("crate", MeshSpec::box({-0.5, 0, -0.5}, {0.5, 1, 0.5}, GroupSpec::named("planks")));
    b.addMesh("trough", MeshSpec::openBox({-1, 0, -0.5}, {1, 0.6, 0.5}, GroupSpec::named("planks")));
    b.addMesh("balloon", lumpySolid(44, 3.0, 0.0, 1.0, 2, GroupSpec::named("silk")));

    b.addLight(LightSpec::directional("sun", {0.3, -1.0, 0.2}).withBias(0.05));

    // Houses (footprint radius ~7 m); the origin sits on the lowest ground under it.
    const std::array<std::array<double, 3>, 3> houses = {{{30, 40, 0}, {150, -60, 30}, {-60, 150, 90}}};
    std::vector<Reserved> reserved;
    for (const auto& h : houses) {
        b.addModel("house", placed({h[0], groundUnder(b, h[0], h[1], 7.0), h[1]}, h[2]));
        reserved.push_back({h[0], h[1], 13.0});
    }

    // Lamp beside house 1 (outside it), torch over a clearing in chunk (-1,-1).
    const glm::dvec3 lamp{22, mm(*b.terrainHeightAt(22, 30) + 4.0), 30};
    b.addLight(LightSpec::point("lamp", lamp, 25));
    const glm::dvec3 torch{-50, mm(*b.terrainHeightAt(-50, -50) + 6.0), -50};
    b.addLight(LightSpec::spot("torch", torch, {0.2, -1.0, 0.1}, 20, 30));
    reserved.push_back({lamp.x, lamp.z, 3});
    reserved.push_back({torch.x, torch.z, 2});
    b.addModel("sign", placed({24, groundUnder(b, 24, 33, 0.2), 33}, 20));
    b.addModel("trough", placed({-20, groundUnder(b, -20, 30, 1.2) + 0.1, 30}, 10));  // rests, slightly raised
    reserved.push_back({24, 33, 2});
    reserved.push_back({-20, 30, 3});

    // Objects whose true masks are 0 for every light (see README.md written beside them):
    // a crate inside closed house 1, above its floor and below its roof: no lit point.
    const double house1 = groundUnder(b, 30, 40, 7.0);
    b.addModel("crate", placed({29.5, house1 + 2.5, 39.5}, 15), "5A3B1E00-00000000-00000000-000000C1");
    b.expect("5A3B1E00-00000000-00000000-000000C1", 0, 0, "inside closed house 1: no lit point");
    // A time capsule 6 m under the terrain: the terrain (opaque) hides it from the sun, and
    // the lamp and torch do not reach it.
    b.addModel("crate", placed({-20, *b.terrainHeightAt(-20, 60) - 6.0, 60}), "5A3B1E00-00000000-00000000-000000C2");
    b.expect("5A3B1E00-00000000-00000000-000000C2", 0, 0, "6 m under the terrain: no lit point");
    reserved.push_back({-20, 60, 3});
    // A balloon 1 km up over the far corner: the sun's rays through it travel on +x/+z and
    // leave the world (x, z < 200 m) while still far above anything, so nothing receives.
    b.addModel("balloon", placed({180, 1000, 180}), "5A3B1E00-00000000-00000000-000000C3");
    b.expect("5A3B1E00-00000000-00000000-000000C3", 0, 0, "1 km up: its shadow leaves the loaded world");

    // A tree in the torch's cone, so the spot light has a caster.
    b.addModel("tree", placed({-47, groundUnder(b, -47, -46, 0.3) - 0.2, -46}, 12));
    reserved.push_back({-47, -46, 3});

    // Rocks and trees scattered per chunk, away from everything reserved and each other.
    DeterministicRng rng(20240607);
    const char* rocks[] = {"rock_a", "rock_b", "rock_c"};
    auto freeSpot = [&](int gx, int gz, double clearance) {
        for (;;) {
            const double x = gx * kChunk + rng.uniform(6, 94), z = gz * kChunk + rng.uniform(6, 94);
            bool ok = true;
            for (const Reserved& r : reserved) ok = ok && std::hypot(x - r.x, z - r.z) > r.radius + clearance;
            if (ok) {
                reserved.push_back({x, z, clearance});
                return std::array<double, 2>{x, z};
            }
        }
    };
    for (int gx = -1; gx <= 1; ++gx)
        for (int gz = -1; gz <= 1; ++gz) {
            for (int k = 0; k < 3; ++k) {
                const double scale = rng.uniform(0.6, 2.2);
                const auto [x, z] = freeSpot(gx, gz, 2.5 * scale);
                // Sunk 0.25 m per metre of radius (a third to a half of its half-height) so
                // that it sits in the ground rather than on it.
                const double y = groundUnder(b, x, z, scale) - 0.25 * scale;
                b.addModel(rocks[rng.below(3)], placed({x, y, z}, rng.uniform(0, 360), scale));
            }
            for (int k = 0; k < 3; ++k) {
                const auto [x, z] = freeSpot(gx, gz, 3.0);
                b.addModel("tree", placed({x, groundUnder(b, x, z, 0.3) - 0.2, z}, rng.uniform(0, 360)));
            }
        }
    // Pebbles marked castsShadow=false: never casters, and not in the shadow map, so they block
    // no light (semantics.md condition 1); still receivers.
    for (int k = 0; k < 2; ++k) {
        const auto [x, z] = freeSpot(1, 0, 1.0);
        b.addModel("rock_b", placed({x, groundUnder(b, x, z, 0.3) - 0.05, z}, 40.0 * k, 0.3), "", false);
    }

    // Things the tool must carry through unchanged.
    b.addChunkXml(0, 0,
                  "<!-- Hand-placed village square: keep this comment when baking -->\n"
                  "<editorInfo author=\"level-design\" revision=\"7\">\n"
                  "  <note> lamp, sign and house layout v2 </note>\n"
                  "</editorInfo>");
    return b;
}

const char* const kSampleSpaceReadme = R"(# Sample space

Written by tools/make_sample_space.cpp (do not edit by hand; re-run the tool). Format:
shared/spec/scene-format.md.

- 3 x 3 chunks of 100 m, gx and gz in -1..1, gently hilly terrain (33 x 33 samples each,
  heights stored between -10 m and +20 m).
- Rocks (three irregular closed meshes), trees (opaque trunk group 0, alpha-tested leaf
  cards group 1 via MTL map_d), three houses (walls group 0, roof group 1), a sign whose
  board is made two-sided by a .model override, a trough (open mesh), two pebbles with
  castsShadow false.
- Lights: 1 "sun" directional (0.3, -1, 0.2), bias 0.05; 2 "lamp" point, range 25,
  beside house 1; 3 "torch" spot, cone 30 degrees, range 20, in chunk (-1,-1).
- Chunk 00000000o.chunk holds a comment and an unknown <editorInfo> element that a bake
  must keep.

Objects whose true mask is 0 for every light (a bake may keep them as undecided, never
the other way round):

| uuid                                | what                       | why                              |
|-------------------------------------|----------------------------|----------------------------------|
| 5A3B1E00-00000000-00000000-000000C1 | crate inside house 1       | no lit point (closed walls/roof) |
| 5A3B1E00-00000000-00000000-000000C2 | capsule 6 m under terrain  | no lit point (terrain above)     |
| 5A3B1E00-00000000-00000000-000000C3 | balloon 1 km up            | its shadow leaves the world      |
)";

}  // namespace shadowcull::testing
