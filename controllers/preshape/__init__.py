"""The hand's pose and pre-shape before a grasp (section 5.2, Posture Control and Wrench Closure):
candidate palm poses, the palm-pose search, the lateral grasp search, and the moves that take
the hand to a pre-shape beside the block."""
