"""Pure JAX, nondimensional physics, one folder by role: the sheet and its laws here
(materials, friction, the vector field, boundary conditions, protocols), the rigid bodies in
:mod:`.bodies`, the paper's static model in :mod:`.static`, the implicit solvers in
:mod:`.solver`, and the run driver (stages, members, batches) in :mod:`.driver`. Imports go
one way: :mod:`.driver` -> :mod:`.solver` -> the sheet and bodies."""
