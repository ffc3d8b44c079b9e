"""Independent float64 references in NumPy, the yardsticks of the tests and benchmarks: `ballistic`
(the whole no-collision pipeline, in the paper's explicit frame form) and `collisions` (an
event-driven simulation of small clouds with exact collision times, the same laws)."""
