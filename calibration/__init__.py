"""Re-measure the gait table (Figure 4) from MuJoCo physics and fit gait parameters to it."""
