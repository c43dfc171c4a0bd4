"""Pure JAX, nondimensional physics: materials, friction, the paper's march, the sheet, protocols,
the solver driver."""
