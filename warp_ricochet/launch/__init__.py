"""Launch: where each pellet starts (sampled in the kernels from (seed, index), or read from a pellet file)."""
