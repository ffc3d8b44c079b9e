"""Constants of the dense phase: pellet phases, the global and per-shot flags, and the stepping's
tuning (see docs/collisions.md). Each shot's clock is `state.make_state`'s `Clock`."""

from ..core.release import ENTERED_GROUND, FLIGHT_ENDED
from ..scene import CHECKPOINT_STEPS

# pellet phases; ENDED: landed after its last ricochet, or at rest on a surface; ENTERED: its flight
# ended in the ground (a penetration law, or sunk in water: physics.ground)
FLYING, ENDED, ENTERED = 0, FLIGHT_ENDED, ENTERED_GROUND
# global flags (int32 array): a shot waits for a rebuild; shots still stepping; list overflow; a
# shot's skin widened
FLAG_STALL, FLAG_REMAINING, FLAG_OVERFLOW, FLAG_WIDENED = 0, 1, 2, 3
NUM_FLAGS = 4
# a step cut at an unresolved event still advances by this fraction of itself (a pair the law does
# not collide, e.g. one closing within rounding, can never stop the clock)
MIN_CUT_FRACTION = 1.0 / 64.0
HORIZON_RADII = 4.0
# per-shot int flags (shots x 6): waits for a rebuild, finished, a pair or ricochet still ahead,
# its lists are rebuilt at the next build (a shot's lists are rebuilt when it needs it, whatever
# the other shots need, so its list-dependent diagnostics do not depend on the chunk), in air its
# pellets leap at this checkpoint (dense.leap), its co-moving frame is due (dense.frame)
SHOT_STALL, SHOT_DONE, SHOT_BUSY, SHOT_REBUILD, SHOT_LEAP, SHOT_FRAME = 0, 1, 2, 3, 4, 5
CHECKPOINT = 2  # shot_flags[s, SHOT_STALL]: waits at a checkpoint (1: waits for a rebuild)
NUM_SHOT_FLAGS = 6
# shot_flags[s, SHOT_FRAME]: its frame follows its flying pellets (a checkpoint, a leap); its
# frame and its arrival window at the launch
FRAME_RECENTRE, FRAME_START = 1, 2
# a shot's frame sums are taken over blocks of this many pellets (one thread a block on CUDA),
# each in pellet order, then the blocks in order: deterministic, and one block (the whole shot,
# in order) for shots up to this size
FRAME_BLOCK = 1 << 14
# hash-grid cells CELL_REACHES reaches wide: a query visits 2 x 2 x 2 cells, not 3 x 3 x 3 (the
# lists are sparse, about one neighbour per pellet in the paper's shot: the cells cost, not the candidates)
CELL_REACHES = 2.0
BLOCK_STEPS = CHECKPOINT_STEPS  # steps between checkpoints (the host reads three integers there, never inside a block)
# the adaptive step lets a list last this many steps at the current speeds: a list built at a
# checkpoint lasts its block (of the default 8 steps; frame_every sets another) with a step to
# spare (speeds change in a block)
SKIN_STEPS = float(BLOCK_STEPS + 1)
# a pellet within this fraction of half its skin since the build, moving at most half the skin /
# SKIN_STEPS in a step (the adaptive step), ends the step within 0.96 of it: no check needed
SKIN_EDGE = 0.85
NEVER_VALUE = 1e30  # s: no event ahead
QUIET_STEP_VALUE = 1.0  # s: the longest step, when nothing moves relative to the drift
TINY_SPEED_VALUE = 1e-30  # m/s: a floor under speeds that divide
CELL_MARGIN = 1.001  # cells this much wider than the distance they are for: rounding cannot split a pair two cells apart
# in air: the longest leap (s); the bound on a pellet's air acceleration over a leap takes its
# speed relative to the air up by |g| times this (dense.leap)
LEAP_MAX_VALUE = 0.05
TINY_ACCELERATION_VALUE = 1e-30  # m/s^2: a floor under air accelerations that divide
# launches of bounded duration for large shots on CUDA (the host waits for each and checks for an
# interrupt between them): a horizon launch covers at most about this many pairs of the chunk (a
# chunk of fewer pellets x count / 2: one launch, as before), a separation launch at most this
# many pellets a shot (smaller shots: one launch)
HORIZON_PAIRS_PER_LAUNCH = 1 << 30
SEPARATION_PELLETS_PER_LAUNCH = 1 << 15
# in air: a pellet's kick lasts at most this many steps (dense.air)
KICK_STEPS = BLOCK_STEPS
