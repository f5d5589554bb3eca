"""Controllers of graspsim (section 5.2 of the paper), by role and in layers (bottom first):
``grasp`` (the paper's grasp mathematics, no simulator), ``planning`` (harmonic functions,
configuration space, the robot's belief of the world), ``posture`` (mink posture control),
``reach`` (Coarse and Fine Reach), ``hand`` (fingers, grip, tendon control), ``deliver`` (plan
and carry out a delivery) and ``preshape`` (palm poses, the lateral grasp search, the moves to a
pre-shape). ``errors`` and ``timing`` are shared by all of them."""
