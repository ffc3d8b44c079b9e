"""An impact on a surface with the ground's laws (`physics.ground`), as the core's landing part,
its continuation to rest (`core.rest`) and the dense phase (`dense.events`) all apply it.

- `drawn(material, normal, velocity, seed, pellet, impact)`: the ground's draw for this impact
  (rough ground's tilted normal and scattered restitution and friction, keyed by (seed, pellet,
  impact)) and whether the pellet enters the ground there (steeper than the critical angle);
- `rebound(material, normal, velocity, spin, physics)`: the impact law (eqs. 1-25,
  `physics.contact`), or the skip off a liquid: (velocity', spin', slipped; a skip never slips).

Built without the ground's laws (`with_laws` False: a scene whose surfaces have none,
`spec.RunSpec.ground`) they compile to the inputs, 0 and the impact law alone.
"""

import functools
from types import SimpleNamespace

import warp as wp

from .contact import make_contact
from .ground import make_ground
from .types import types_for


@functools.cache
def make_ground_contact(precision: str, with_laws: bool) -> SimpleNamespace:
    """`drawn` and `rebound` of one precision (module docstring)."""
    t = types_for(precision)
    vec3, Physics, Material = t.vec3, t.Physics, t.Material
    impact = make_contact(precision)[2]
    ground = make_ground(precision)

    @wp.func
    def drawn(material: Material, normal: vec3, velocity: vec3, seed: wp.int32, pellet: wp.int32, impact: wp.int32):
        """(material, normal, enters): the ground's draw for this impact and whether the pellet
        enters the ground (`ground.draw`, `ground.embeds`)."""
        if wp.static(with_laws):
            drawn_material, tilted = ground.draw(material, normal, velocity, seed, pellet, impact)
            return drawn_material, tilted, ground.embeds(drawn_material, velocity, tilted)
        return material, normal, wp.int32(0)

    @wp.func
    def rebound(material: Material, normal: vec3, velocity: vec3, spin: vec3, physics: Physics):
        """(velocity', spin', slipped) off a surface of `material` and (drawn) `normal`: the impact
        law, or a skip off a liquid (`ground.skip`)."""
        velocity_after, spin_after, slipped = impact(material, normal, velocity, spin, physics)
        if wp.static(with_laws):
            if material.liquid != 0:
                velocity_after, spin_after = ground.skip(material, velocity, normal, spin)
                slipped = wp.int32(0)
        return velocity_after, spin_after, slipped

    return SimpleNamespace(drawn=drawn, rebound=rebound)
