"""The hand and its fingers (section 5.2, Wrench Closure and Grasp Object): where each finger can
put its fingertip, which finger takes which contact, whether the hand can take a grasp, closing
with a touch guard, the squeeze, and the tendon-driven hand's joint control."""
