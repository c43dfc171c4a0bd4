"""What a run does while XLA compiles its step (:func:`dynslip.physics.simulate.compile_step`
runs these in a thread: XLA releases the GIL and leaves about half a core of this machine's two
free): work the run would do after the compile anyway, done before it is needed. Nothing here
may fail a run: the thread drops errors, and the call that was warmed reports them."""

from __future__ import annotations

__all__ = ["beside", "import_outputs", "prepare_summary"]


def beside(sc, model, writes: bool) -> list:
    """The warm-ups of a forming run: import what writing the results needs (where the run
    writes, :func:`import_outputs`), and compile the summary's clearance of the held bodies for
    the run's mesh (:func:`prepare_summary`)."""
    out = [import_outputs] if writes else []
    if model.bodies:
        out.append(lambda: prepare_summary(sc, model.mesh.n))
    return out


def prepare_summary(sc, nodes: int) -> None:
    """Compile the distance of a frame to each held body, which the summary's
    :func:`~dynslip.analysis.clearance.body_contacts` runs frame by frame (0.3 s of a cold run
    with the tube and the bottle)."""
    from dynslip.analysis.clearance import prepare

    prepare([body for _, body, _ in sc.physics.named_bodies()], nodes)


def import_outputs() -> None:
    """Import what writing the results needs (:func:`dynslip.data.files.import_writers`, and
    matplotlib's figures): about 0.7 s of a cold run."""
    from dynslip.data.files import import_writers

    import_writers()
    import dynslip.analysis.summary  # noqa: F401 - xarray and pandas with it (0.2-0.4 s)
    import dynslip.plot.forming  # noqa: F401
    import dynslip.plot.world  # noqa: F401
