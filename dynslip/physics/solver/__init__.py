"""The implicit solvers of a save segment: load stepping with Newton on the motion
(:mod:`.newton`, its residual :mod:`.increment` and matrix :mod:`.newton_matrix`), on the whole
state (:mod:`.loadstep`), the block-tridiagonal linear solver (:mod:`.linalg`), diffrax's time
stepping and the choice among them (:mod:`.methods`), and the local fixes of pinned libraries
(:mod:`.upstream`). They import the sheet and the bodies, never the driver."""
