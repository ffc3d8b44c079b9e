"""The dense phase of pellet-pellet collisions (the paper neglects them): pellets in flight colliding with each other and with the planes, time-stepped
on a hash grid, until no pair can touch again; then every pellet goes to the core's exact flight.

One thread per pellet; every pellet belongs to one shot (rows [s * count, (s + 1) * count)) and
meets only pellets of its own shot. Each shot has its own clock and step, so a shot's results do
not depend on which shots share a launch (chunk-size invariance) and finished shots stop early.

Each pellet carries a *reference state*: position and velocity at the time of its last event
(launch, plane impact or pair collision), from which its flight is the exact parabola of eq. (36);
nothing is integrated. Gravity is the same for all pellets, so the relative motion of a pair is
linear and its time of contact is exact (no tunnelling); plane contacts are the exact
parabola-plane times of `physics.ballistic`, from the same reference states as the core, so a pellet that
never meets another gets bitwise the collisions-off result.

Events in a step are resolved in `rounds`: each pellet knows its earliest event (plane contact,
or contact with a listed neighbour); a plane event, or a pair event that both pellets picked
(mutual), is applied at its exact time if it falls in the step. A pellet takes part in at most
one event per round, and a pair is applied by one thread, in place: impulses are never summed,
momentum is conserved, energy never rises, and the result does not depend on thread order. A
pair event still ahead after the last round ends the shot's step at its time (no pellet flies
past it into its partner); it is resolved first in the next step.

A pellet's earliest event is kept from step to step and found again only when it is stale: when
it or a neighbour changed, or its list was rebuilt. A pair's contact time is computed from the
later of the two reference times (as reference.collisions does), so it is one number whoever
asks and whenever, and a kept event is the one a new search would find: results do not depend
on when events are found again. Most pellets in most steps have no event, and their step costs
a few reads.

On the CPU a kernel runs on one thread anyway, and entering a Warp kernel thread costs more
than a quiet pellet's step (its struct arguments and locals are set up per thread), so the
per-pellet kernels loop over `pair.span` pellets per thread (all of them on the CPU, one on
CUDA). On the CPU the whole dense phase of a group of shots is one launch of `phase_kernel`
(without trajectory frames; with them a block of steps is one launch of `block_kernel`): each
shot in turn builds its lists, passes its checkpoints and steps, with the same per-pellet
functions in the order the per-step kernels run them (the results are bitwise the same).

Each pellet keeps, with its event, when it would leave its skin after it; the earliest of those
among a round's events in the step ends the step, and only events up to it are applied (a plane
rebound can be far faster than the step was sized for).

Neighbour lists (reach 2R + skin) are built in co-moving coordinates (positions relative to each
shot's ballistic drift): on CUDA from a `wp.HashGrid` whose groups keep shots apart (overlapping
shots cost nothing), on the CPU from `cell_lists_kernel` (the same lists; HashGrid's CPU build has
a fixed cost larger than a shot's whole build). A shot's lists are rebuilt only when it needs it:
a pellet could move by half the skin relative to the drift (checked before each step; a step that
could break a list waits for the rebuild), or its frame was recentred at a checkpoint; the
adaptive step lets a list last SKIN_STEPS steps, one more than a block, so the lists built at a
checkpoint last its block. The adaptive step depends on the shot's own speeds only (a skin cut,
rare, on its own lists' build points), so its results do not depend on the other shots.

At checkpoints (every `block_steps` of its own steps) a shot stops stepping once its arrival
window is over (its undisturbed pellets have all met their first surface and the cloud has passed
it) and no pair of the shot can meet again (all pairs, not only listed ones, checked exactly); see
docs/collisions.md for what this neglects. At each checkpoint a shot past that window finds its
next event over all its pairs and planes and jumps to it, so a pair of rebounds converging slowly
for tens of milliseconds does not cost tens of thousands of small steps.

Modules, one stage each: `kit` (`dense_kit(spec)`: the namespace every stage's factory starts from:
types, structs, constants, eq. 36, the geometry and the flights), `state` (the Cloud and Pair
structs, the Cloud's arrays grouped by the stage that owns them, their allocation), `frame` (each
shot's co-moving frame, reference states), `events` (plane and pair contacts), `rounds` (finding
and applying a step's events), `lists` (neighbour lists), `step` (a step; the CPU's block),
`checkpoint` (a shot's horizon, stop or jump), `leap` (in air, the jump: the pellets flown through
it), `air` (the air's kicks), `ends` (launch, release, totals), `watch` (the hazard along each
pellet's path, kept from its launch and handed to the core), `kernels` (thin kernels), `phase`
(the host loop), `schedule` (shots onto chunks and threads), `constants`.
"""
