"""Where a pellet's path ends (runs with physics.until = "rest", docs/ground.md): the codes of the
per-pellet field `rest.state` and their names (its HDF5 attribute `states`, in code order). This
module imports nothing: the kernels, the writer and the reports share it.

- AT_REST: on a surface, slower than physics.rest_speed and held there;
- EMBEDDED: it entered water or soft ground (its rest position is where it entered);
- ESCAPED: it never meets a surface again (rest position and velocity NaN, time inf);
- NOT_FINISHED: its budget (physics.max_impacts, physics.max_steps) ran out first: where it was
  then is kept, and it is counted apart, never as at rest.
"""

AT_REST, EMBEDDED, ESCAPED, NOT_FINISHED = 0, 1, 2, 3
STATES = ("at rest", "embedded", "escaped", "not finished")  # by code
STOPPED = (AT_REST, EMBEDDED)  # the end states with a rest distance in the statistics
