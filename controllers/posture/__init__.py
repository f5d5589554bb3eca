"""Posture Control (section 5.2; Grupen & Souccar, ref. [16]): mink's differential IK keeps the
fingertips on their targets while the hand's manipulability is maximized in the null space."""
