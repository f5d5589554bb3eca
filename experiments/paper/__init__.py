"""The paper's experiments on the grasp core (sections 2-4, the appendices): Table 1, every
experiment over several seeds (``python -m experiments.paper reproduce``), its report and
figures."""
