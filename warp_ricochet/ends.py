"""How a pellet followed to rest (`physics.until = "rest"`) ends: the codes of /pellets/rest/state.

The dataset's attribute `states` lists NAMES by code. This module imports nothing.
"""

AT_REST, EMBEDDED, ESCAPED, NOT_FINISHED = 0, 1, 2, 3
NAMES = ("at rest", "embedded", "escaped", "not finished")
