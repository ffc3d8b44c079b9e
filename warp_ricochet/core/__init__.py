"""The core: one fused kernel a chunk that launches each pellet (or continues it from the dense
phase), flies it to each surface, applies the impact law, flies it to its landing, writes its
outputs and adds it to the statistics."""
