"""What every function factory of the dense phase starts from, built once per spec: `dense_kit(spec)`.

One namespace holds the types and structs (`scalar`, `vec3`, `Surfaces`, `Physics`, `Cloud`, `Pair`,
`Outputs`, `Source`), the scalar constants, the physics every stage calls (`ballistic`: eq. 36 and
the roots of `physics.ballistic`; `geo`: the surfaces of `physics.geometry`; `flight`: the exact
flight between events; `run_flight`: the run's own flight, integrated in air), the output writers
and the spec's switches (`PLATES`: the scene has finite plates, whose rules `geo` and the flights then
compile in: docs/geometry.md). The physics factories are keyed by the precision string alone.
"""

import functools
from types import SimpleNamespace

from ..core.outputs import make_outputs
from ..launch.source import make_source
from ..physics.ballistic import EPSILON, ROUNDING, make_ballistic
from ..physics.flight import make_flight
from ..physics.geometry import make_geometry
from ..physics.types import types_for
from .constants import NEVER_VALUE, QUIET_STEP_VALUE, TINY_SPEED_VALUE
from .state import make_state


@functools.cache
def dense_kit(spec) -> SimpleNamespace:
    """The dense phase's shared namespace for `spec` (module docstring). `flight` is the exact
    (ballistic) flight between events, with the touching band off in air, whose kicks would meet
    a plane early within the band (`physics.geometry`, docs/air.md, section 3.2)."""
    precision = spec.precision
    t = types_for(precision)
    Cloud, Pair = make_state(precision)
    scalar = t.scalar
    outputs = make_outputs(precision)
    return SimpleNamespace(
        precision=precision,
        scalar=scalar,
        vec3=t.vec3,
        Surfaces=t.Surfaces,
        Physics=t.Physics,
        Cloud=Cloud,
        Pair=Pair,
        Outputs=outputs.Outputs,
        Source=make_source(precision, spec.from_file, spec.pattern, spec.stations).Source,
        NEVER=scalar(NEVER_VALUE),
        TINY_SPEED=scalar(TINY_SPEED_VALUE),
        QUIET_STEP=scalar(QUIET_STEP_VALUE),
        CLOSING_TOLERANCE2=scalar((ROUNDING * EPSILON[precision]) ** 2),
        opts={"module": "unique", "enable_backward": False},
        ballistic=make_ballistic(precision),
        geo=make_geometry(precision, plates=spec.plates),
        flight=make_flight(precision, spec.static_planes, snap=spec.flight != "air", plates=spec.plates),
        run_flight=make_flight(precision, spec.static_planes, spec.flight, spec.air_laws, plates=spec.plates),
        outputs=outputs,
        AIR=spec.in_air,
        BOUNCES=spec.bounces,
        WRITE=bool(spec.core_fields),
        STATIC_PLANES=spec.static_planes,
        PLATES=spec.plates,
        GROUND=spec.ground,
    )
