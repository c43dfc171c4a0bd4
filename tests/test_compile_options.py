"""The segment step's XLA compile options (simulate.COMPILER_OPTIONS, docs/speed.md): the pinned
jaxlib accepts them and they change the code, not the answer (to rounding); a jaxlib that does
not know one compiles with its defaults instead of failing; a large mesh keeps the defaults."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dynslip.physics.driver.simulate as sim


def _f(x):
    # a fused elementwise-and-reduce program, the kind the fusion emitters compile
    return jnp.sum(jnp.tanh(x) * jnp.exp(-x * x)) + jnp.cumsum(jnp.sin(x))


X = jnp.linspace(-2.0, 2.0, 257)


def test_options_known_to_the_pinned_jaxlib():
    lowered = jax.jit(_f).lower(X)
    lowered.compile(compiler_options=sim.COMPILER_OPTIONS)  # raises on an unknown option
    np.testing.assert_allclose(sim.compile_step(lowered, 50)(X), lowered.compile()(X), rtol=1e-14)


def test_unknown_option_falls_back_to_the_defaults(monkeypatch):
    lowered = jax.jit(_f).lower(X)
    monkeypatch.setattr(sim, "COMPILER_OPTIONS", {"xla_cpu_no_such_option_here": True})
    with pytest.raises(jax.errors.JaxRuntimeError, match="No such compile option"):
        lowered.compile(compiler_options=sim.COMPILER_OPTIONS)
    np.testing.assert_allclose(sim.compile_step(lowered, 50)(X), _f(X), rtol=1e-14)


def test_large_meshes_keep_the_defaults(monkeypatch):
    """Past FAST_COMPILE_NODES the step asks for XLA's own default, the fusion emitters on,
    which the package turns off for every other program (dynslip._jaxconfig: the process's
    XLA_FLAGS say so); the small mesh's options are not asked for (an unknown one would
    raise)."""
    import os

    assert "--xla_cpu_use_fusion_emitters=false" in os.environ["XLA_FLAGS"]
    lowered = jax.jit(_f).lower(X)
    monkeypatch.setattr(sim, "COMPILER_OPTIONS", {"xla_cpu_no_such_option_here": True})
    calls = []
    real = type(lowered).compile

    def spy(self, compiler_options=None, **kw):
        calls.append(compiler_options)
        return real(self, compiler_options, **kw)

    monkeypatch.setattr(type(lowered), "compile", spy)
    large = sim.compile_step(lowered, sim.FAST_COMPILE_NODES + 1)
    sim.compile_step(lowered, sim.FAST_COMPILE_NODES)
    assert calls[0] == sim.LARGE_COMPILER_OPTIONS == {"xla_cpu_use_fusion_emitters": True}
    assert calls[1] == sim.COMPILER_OPTIONS and calls[2] is None  # refused: the defaults
    np.testing.assert_allclose(large(X), _f(X), rtol=1e-14)

