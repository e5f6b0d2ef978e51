// `shadowcull explain SPACE CHUNK OBJECT [--light N]`: bakes one chunk (nothing written)
// and prints, for one object, why each (group, light) bit is what it is: the verdict, the
// deciding stage and its evidence (witness ray or proof), with the effects the bake
// simulated for the chunk and any warnings.
#pragma once

#include <iosfwd>
#include <string>

namespace shadowcull::cli {

struct ExplainOptions {
    std::string spaceDir;
    std::string chunk;         // "XXXXZZZZo" or "XXXXZZZZo.chunk"
    std::string object;        // uuid, or element index (a number) among the chunk's models/terrains
    std::string resourceRoot;  // --res; empty: as space.xml says
    int light = 0;             // 1-based light number; 0 = all
};

// Exit 0 when explained; 3 (kExitBadInput) when the chunk or object does not exist (the
// message says which and lists what there is); 2 for a light number out of range; a failed
// bake exits as `bake` would.
int runExplain(const ExplainOptions& options, std::ostream& out, std::ostream& err);

}  // namespace shadowcull::cli
