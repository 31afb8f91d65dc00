"""Grasp planning (Alg. 2), its baselines and the picking loop (Alg. 1). No Drake import here."""
