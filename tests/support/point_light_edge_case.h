// The case issue 34's property run found (seed 3434): a point light on the line of a
// caster's edge, in the plane of that edge and a receiver. ShadowQuery::addSlabs took a
// plane through the light and the edge as bounding on raw double signs and rejected the
// receiver, which the exact frustum holds; as a scene, a false cull (fixed by 839e880).
// Window-local coordinates, exactly as found.
#pragma once

#include <array>

#include <glm/vec3.hpp>

namespace shadowcull::testing::point_light_edge_case {

inline const std::array<glm::dvec3, 3> kCaster = {glm::dvec3(0x1.ef88c37d868ccp-2, -0x1.fa5c85a850db6p-1, -0x1.9f5d09fea6ed2p+0),
                                                  glm::dvec3(-0x1.3793752073c22p+11, 0x1.8a77d4aae1602p+12, -0x1.9f5d09fea6ed2p+0),
                                                  glm::dvec3(0x1.96a73fefaa6cbp+9, 0x1.a51209385ae59p+12, -0x1.a0dd6c3a07304p+0)};
inline const std::array<glm::dvec3, 3> kReceiver = {glm::dvec3(0x1.2e4b0b9876164p-1, -0x1.9255bb8c038ep+0, -0x1.9f5d09fea6ed2p+0),
                                                    glm::dvec3(-0x1.1de1eed91c6bap+0, -0x1.77a86466444cp+0, -0x1.9f5d09fea6ed2p+0),
                                                    glm::dvec3(-0x1.1d826c65d279ap+1, -0x1.13d8997f9e78ap+1, -0x1.9f5d09fea6ed2p+0)};
inline const glm::dvec3 kLamp(-0x1.3783f8da57d5fp+10, 0x1.8a6801c6b41dap+11, -0x1.9f5d09fea6ed2p+0);

}  // namespace shadowcull::testing::point_light_edge_case
