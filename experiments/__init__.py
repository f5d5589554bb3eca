"""Studies built on the library, at the top of its layers: the paper's experiments on the grasp
core (:mod:`experiments.paper`), the physical grasp study (:mod:`experiments.physics`) and the
task-cycle bench (:mod:`experiments.bench`). Nothing below imports them."""
