"""Planning in the arm's configuration space (section 5.2): harmonic functions on a grid
(Connolly & Grupen), the collision checks of arm and hand configurations, and the world as the
robot believes it, against which every plan is checked."""
