// Writes the known-answer glTF scene of tests/support/gltf_scenes.h: data/gltf-courtyard
// holds its output (README.md shows import, bake, export on it).
//   make_gltf_scene OUT.glb|OUT.gltf [--moved]

#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "tests/support/gltf_scenes.h"

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: make_gltf_scene OUT.glb|OUT.gltf [--moved]\n");
        return 2;
    }
    const std::string out = argv[1];
    const bool moved = argc > 2 && std::strcmp(argv[2], "--moved") == 0;
    const shadowcull::testing::KnownGltfScene k = shadowcull::testing::courtyardScene(moved);
    const bool glb = out.size() > 4 && out.compare(out.size() - 4, 4, ".glb") == 0;
    std::ofstream f(out, std::ios::binary);
    f << (glb ? k.scene.glb() : k.scene.gltf());
    f.close();
    if (!f) {
        std::fprintf(stderr, "make_gltf_scene: could not write %s\n", out.c_str());
        return 4;
    }
    std::printf("wrote %s (%s): expected masks per node:\n", out.c_str(), k.name.c_str());
    for (const auto& [name, masks] : k.expected) {
        std::printf("  %-13s", name.c_str());
        for (uint32_t m : masks) std::printf(" %u", m);
        std::printf("\n");
    }
    return 0;
}
