"""The physical parameters of a built world are traced values (issue 55, item 1): the
material's, the penalty's and the ball friction law's floats are 0-d arrays, so that a sweep
over any of them runs one compiled segment step, and a transformation reaches them.

The let-go path of scenarios/method2_let_go.yaml at 20 nodes (0.2 s a run, once compiled).
"""

from __future__ import annotations

from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.api import load
from dynslip.physics.driver import simulate as sim
from dynslip.physics.driver.member import MemberRun
from dynslip.physics.materials import Gent, MooneyRivlin

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "method2_let_go.yaml"
SHORT = {"numerics.nodes": 20}
JMS = (30.0, 40.0, 50.0)
SCALARS = ("theta_max", "ball_z", "ball_reaction", "clamp_force", "energy_elastic")


def world(**values):
    return load(SCENARIO, set={**SHORT, **values}).world()


def run(w):
    return sim.simulate(w.model, w.protocol, **w.simulate_kwargs())


@pytest.mark.parametrize("jm", [1e-3, 0.5, 5.0, 50.0, 97.2, 1e4])
def test_gent_lock_closed_form_is_the_cubic_root_and_traces(jm):
    """The trigonometric closed form of the largest root of l^3 - (J_m + 3) l + 2 = 0 is
    the largest of numpy's roots; under jit with J_m traced it gives the same, and its
    derivative is the implicit one, dl/dJ_m = l / (3 l^2 - J_m - 3)."""
    lock = float(Gent(jm=jm).max_uniaxial_stretch())
    ref = float(np.max(np.roots([1.0, 0.0, -(jm + 3.0), 2.0]).real))
    assert lock == pytest.approx(ref, rel=1e-12)
    assert lock**2 + 2.0 / lock == pytest.approx(jm + 3.0, rel=1e-12)
    f = jax.jit(lambda j: Gent(jm=j).max_uniaxial_stretch())
    l, dl = jax.jvp(f, (jnp.float64(jm),), (jnp.float64(1.0),))
    assert float(l) == pytest.approx(lock, rel=1e-14)
    assert float(dl) == pytest.approx(lock / (3 * lock**2 - jm - 3.0), rel=1e-9)


def test_the_world_holds_its_physical_parameters_as_arrays():
    """Material, penalty and friction law: every float leaf is a float64 array; ints, the
    mesh's static sizes, the solver's settings and the held bodies are as they were."""
    for w in (world(), world(**{"physics.material.model": "mooney_rivlin",
                                "physics.material.c1": 0.4})):
        parts = (w.model.material, w.model.penalty, w.loads["friction"])
        for leaf in jax.tree_util.tree_leaves(parts):
            assert eqx.is_array(leaf) and leaf.dtype == jnp.float64, leaf
    mr = world(**{"physics.material.model": "mooney_rivlin", "physics.material.c1": 0.4})
    assert isinstance(mr.model.material, MooneyRivlin)
    assert float(mr.model.material.c2) == pytest.approx(0.1)


def test_worlds_of_several_jm_share_one_static_key():
    keys = {MemberRun(w.model, w.protocol, **w.loads, settings=w.settings).key
            for w in (world(**{"physics.material.jm": j}) for j in JMS)}
    assert len(keys) == 1


@pytest.fixture(scope="module")
def sweep_runs():
    """The J_m sweep run one member after another from an empty cache of compiled steps,
    counting the segment step's compilations."""
    calls = []
    real = sim.compile_step

    def counting(lowered, nodes):
        calls.append(nodes)
        return real(lowered, nodes)

    sim._COMPILED.clear()
    sim.compile_step = counting
    try:
        results = {jm: run(world(**{"physics.material.jm": jm})) for jm in JMS}
    finally:
        sim.compile_step = real
    return results, calls


def test_a_jm_sweep_compiles_the_segment_step_once(sweep_runs):
    results, calls = sweep_runs
    assert len(calls) == 1
    assert all(r.failed is None for r in results.values())
    assert [r.stats["compile_s"] > 0 for r in results.values()] == [True, False, False]
    # the members are different runs: a stiffer lock (smaller J_m) forms a different pocket
    ends = [float(results[j].frames[-1]["energy_elastic"]) for j in JMS]
    assert len({round(e, 6) for e in ends}) == len(JMS), ends


def test_a_member_of_the_sweep_equals_its_own_program(sweep_runs):
    """J_m = 50 from the shared program against the same run with J_m a Python float
    compiled into its own program (the behaviour before the parameters were traced): equal
    to rounding, amplified by the path's hundreds of Newton-solved increments."""
    results, _ = sweep_runs
    w = world(**{"physics.material.jm": 50.0})
    own = eqx.tree_at(lambda m: m.material, w.model, Gent(jm=50.0))
    assert type(own.material.jm) is float
    ref = sim.simulate(own, w.protocol, **w.simulate_kwargs())
    got = results[50.0]
    assert ref.stats["steps"] == got.stats["steps"]
    assert len(ref.frames) == len(got.frames)
    for name in SCALARS:
        a = np.array([f[name] for f in ref.frames], float)
        b = np.array([f[name] for f in got.frames], float)
        np.testing.assert_allclose(b, a, rtol=1e-8, atol=1e-10, err_msg=name)
