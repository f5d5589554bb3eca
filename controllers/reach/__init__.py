"""The arm's reach (section 5.2): Coarse Reach's harmonic path in the arm's configuration space to
a top or lateral goal, the paths' execution, and Fine Reach's harmonic fields that bring the
fingertips to points on the perceived surface."""
