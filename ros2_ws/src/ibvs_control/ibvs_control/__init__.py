"""Inner joint loop, feedforward and adaptive Youla feedback of the paper (section 4)."""
