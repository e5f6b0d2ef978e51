// The bundled sample space, as a builder: tools/make_sample_space writes it to data/sample,
// and tests bake it moved and lifted.
#pragma once

#include "tests/support/space_builder.h"

namespace shadowcull::testing {

// 3 x 3 chunks of hilly terrain with rocks, trees, houses and three lights (see the .cpp).
SpaceBuilder sampleSpace();

// The README.md written beside the sample space: what it holds and its true zeros.
extern const char* const kSampleSpaceReadme;

}  // namespace shadowcull::testing
