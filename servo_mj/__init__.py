"""MuJoCo side of the ServoBot colony: the robot (``servo_mj.robot``) and the world it walks
in (``servo_mj.world``)."""

import os

# Nothing in this package renders. Without a display, dm_control's automatic OpenGL probing
# warns through GLFW on import; "disable" skips it. A user who renders sets MUJOCO_GL itself
# (egl or osmesa), which this leaves alone.
os.environ.setdefault("MUJOCO_GL", "disable")
