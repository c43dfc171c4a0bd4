"""The segment solvers the tests run, built as a scenario's ``numerics`` builds them
(:meth:`dynslip.schema.forming.FormingNumerics.build_solver`)."""

from dynslip.schema.forming import FormingNumerics


def named_solver(name: str = "load_step", heal_rate: float = 0.0, **numerics):
    """The segment solver of ``numerics.solver = name``, with these ``numerics`` fields (the
    schema's defaults otherwise) and the healing rate ``heal_rate`` (R/s)."""
    return FormingNumerics(solver=name, **numerics).build_solver(heal_rate)
