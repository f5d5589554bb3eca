"""Speed and accuracy benchmarks; each module prints its figures (``python -m benchmarks.X``)."""
