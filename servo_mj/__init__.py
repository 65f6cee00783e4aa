"""MuJoCo side of the ServoBot colony: model loading, gaits, arena, physics sensors, validation."""
