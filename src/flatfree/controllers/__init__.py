"""Controllers: flatness-based (the paper's Section 2) and model-free (Section 3)."""
