"""Engineering analysis of mechanisms: joint reactions and driver efforts, joint coordinates,
kinematic analysis of driven mechanisms, static equilibrium and linearized modes."""
