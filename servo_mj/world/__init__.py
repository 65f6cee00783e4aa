"""The world the physics ServoBot walks in: the arena (``dm_control.mjcf``), rangefinder
sensors, and the physics world the controller interpreter runs against."""
