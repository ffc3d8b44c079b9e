"""The core kernel's per-pellet outputs: the `Outputs` struct, generated from the field registry
(`fields.FIELDS`, the launch, impact, landing and rest stages), and the functions that write one
pellet's rows. An empty array is not written: a run allocates only the fields it asks for.
"""

import functools
from types import SimpleNamespace

import warp as wp

from ..fields import CORE_FIELDS, FIELDS
from ..physics.types import types_for

INTEGER_TYPES = {"int8": wp.int8, "int16": wp.int16, "int32": wp.int32}


def element_type(name: str, precision: str):
    """The Warp type of one element of field `name`."""
    t = types_for(precision)
    kind = FIELDS[name].kind
    return {"vec3": t.vec3, "scalar": t.scalar}.get(kind) or INTEGER_TYPES[kind]


@functools.cache
def make_outputs(precision: str) -> SimpleNamespace:
    """`Outputs` and its writers for one precision."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    members = {
        FIELDS[name].member: (wp.array2d if FIELDS[name].per_bounce or FIELDS[name].per_threshold else wp.array)(
            dtype=element_type(name, precision)
        )
        for name in CORE_FIELDS
    }
    Outputs = wp.struct(
        type(
            "Outputs",
            (),
            {
                "__annotations__": members,
                "__module__": __name__,
                "__qualname__": f"Outputs_{precision}",
                "__doc__": "Per-pellet results (chunk-local rows); an empty array is not written.",
            },
        )
    )

    @wp.func
    def write_initial(out: Outputs, row: wp.int32, position: vec3, velocity: vec3, spin: vec3):
        if out.initial_position.shape[0] > 0:
            out.initial_position[row] = position
        if out.initial_velocity.shape[0] > 0:
            out.initial_velocity[row] = velocity
        if out.initial_angular_velocity.shape[0] > 0:
            out.initial_angular_velocity[row] = spin

    @wp.func
    def write_impact(
        out: Outputs,
        row: wp.int32,
        bounce: wp.int32,
        time: scalar,
        position: vec3,
        velocity_before: vec3,
        angular_velocity_before: vec3,
        velocity: vec3,
        angular_velocity: vec3,
        slipped: wp.int32,
        surface: wp.int32,
    ):
        if out.impact_time.shape[0] > 0:
            out.impact_time[row, bounce] = time
        if out.impact_position.shape[0] > 0:
            out.impact_position[row, bounce] = position
        if out.impact_velocity_before.shape[0] > 0:
            out.impact_velocity_before[row, bounce] = velocity_before
        if out.impact_angular_velocity_before.shape[0] > 0:
            out.impact_angular_velocity_before[row, bounce] = angular_velocity_before
        if out.impact_velocity.shape[0] > 0:
            out.impact_velocity[row, bounce] = velocity
        if out.impact_angular_velocity.shape[0] > 0:
            out.impact_angular_velocity[row, bounce] = angular_velocity
        if out.impact_slipped.shape[0] > 0:
            out.impact_slipped[row, bounce] = wp.int8(slipped)
        if out.impact_surface.shape[0] > 0:
            out.impact_surface[row, bounce] = wp.int16(surface)

    @wp.func
    def mark_missing(out: Outputs, row: wp.int32, bounce: wp.int32):
        """No impact at this bounce: NaN states, slipped and surface -1."""
        missing = vec3(scalar(wp.nan))
        write_impact(out, row, bounce, scalar(wp.nan), missing, missing, missing, missing, missing, -1, -1)

    @wp.func
    def write_landing(
        out: Outputs, row: wp.int32, time: scalar, position: vec3, velocity: vec3, landing_range: scalar, surface: wp.int32
    ):
        if out.landing_time.shape[0] > 0:
            out.landing_time[row] = time
        if out.landing_position.shape[0] > 0:
            out.landing_position[row] = position
        if out.landing_velocity.shape[0] > 0:
            out.landing_velocity[row] = velocity
        if out.landing_range.shape[0] > 0:
            out.landing_range[row] = landing_range
        if out.landing_surface.shape[0] > 0:
            out.landing_surface[row] = wp.int16(surface)

    @wp.func
    def write_hazard(out: Outputs, row: wp.int32, energy: scalar, energy_density: scalar, exceeds: wp.int32):
        if out.hazard_energy.shape[0] > 0:
            out.hazard_energy[row] = energy
        if out.hazard_energy_density.shape[0] > 0:
            out.hazard_energy_density[row] = energy_density
        if out.hazard_exceeds.shape[0] > 0:
            out.hazard_exceeds[row] = exceeds

    @wp.func
    def write_rest(
        out: Outputs,
        row: wp.int32,
        state: wp.int32,
        position: vec3,
        velocity: vec3,
        time: scalar,
        impacts: wp.int32,
        path_length: scalar,
    ):
        """Where the pellet ends (`ends`: `state` one of its codes)."""
        if out.rest_position.shape[0] > 0:
            out.rest_position[row] = position
        if out.rest_velocity.shape[0] > 0:
            out.rest_velocity[row] = velocity
        if out.rest_time.shape[0] > 0:
            out.rest_time[row] = time
        if out.rest_state.shape[0] > 0:
            out.rest_state[row] = wp.int8(state)
        if out.rest_impacts.shape[0] > 0:
            out.rest_impacts[row] = impacts
        if out.rest_path_length.shape[0] > 0:
            out.rest_path_length[row] = path_length

    return SimpleNamespace(
        Outputs=Outputs,
        write_rest=write_rest,
        write_initial=write_initial,
        write_impact=write_impact,
        mark_missing=mark_missing,
        write_landing=write_landing,
        write_hazard=write_hazard,
    )


def outputs_struct(precision: str, device, arrays: dict):
    """An Outputs struct holding `arrays` ({field name: device array}) and empty arrays for the rest."""
    outputs = make_outputs(precision).Outputs()
    for name in CORE_FIELDS:
        f = FIELDS[name]
        arr = arrays.get(name)
        if arr is None:
            arr = wp.empty((0, 0) if f.per_bounce or f.per_threshold else 0, dtype=element_type(name, precision), device=device)
        setattr(outputs, f.member, arr)
    return outputs
