"""Independent float64 references in NumPy, the yardsticks of the tests and benchmarks: `ballistic`
(the whole no-collision pipeline, in the paper's explicit frame form), `collisions` (an
event-driven simulation of small clouds with exact collision times, the same laws), `air`,
`surface_motion` (one pellet followed to rest on a plane) and `path_hazard` (the hazard along its
path: reach distances, map passes and point levels, by brute force on its dense path)."""
