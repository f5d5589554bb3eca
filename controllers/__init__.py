"""Controllers of graspsim: the grasp controller (``controllers.grasp``) and the reach/posture
controllers that act on the simulated arm and hand (section 5.2 of the paper)."""
