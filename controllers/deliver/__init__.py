"""Deliver (section 5.2): plan the delivery (a harmonic path with the block in hand and a set-down
posture at the place point), then carry it out: lift, carry, lower until the table takes the
weight, release and retreat."""
