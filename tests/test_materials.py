"""Energies and tensions of the membrane materials against closed forms (physics.md Section 2)."""

import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.errors import MaterialRangeError
from dynslip.physics.materials import Gent, Hookean, MooneyRivlin, NeoHookean, check_range, tensions
from dynslip.physics.static import check_static_range

MODELS = [Hookean(), NeoHookean(), MooneyRivlin(c1=0.3, c2=0.2), Gent(jm=50.0), Gent(jm=5.0)]


def _t(mat, lt, lp):
    a, b = tensions(mat, jnp.asarray(lt, float), jnp.asarray(lp, float))
    return np.asarray(a), np.asarray(b)


@pytest.mark.parametrize("mat", MODELS, ids=lambda m: m.name)
def test_zero_stress_at_unit_stretch(mat):
    tt, tp = _t(mat, [1.0], [1.0])
    assert abs(tt[0]) < 1e-14 and abs(tp[0]) < 1e-14
    assert abs(float(mat.energy(1.0, 1.0))) < 1e-14


@pytest.mark.parametrize("mat", MODELS[1:], ids=lambda m: m.name)
def test_small_strain_limit_is_hookean(mat):
    """T_model - T_Hookean = O(eps^2) while T = O(eps): the relative gap falls at order 1."""
    hook = Hookean()
    eps = np.array([1e-2, 5e-3, 2.5e-3, 1.25e-3])
    gaps = []
    for da, db in [(1.0, 0.0), (0.0, 1.0), (1.0, -0.7), (0.6, 0.9)]:
        g = []
        for e in eps:
            lt, lp = 1 + da * e, 1 + db * e
            tm = np.array(_t(mat, [lt], [lp])).ravel()
            th = np.array(_t(hook, [lt], [lp])).ravel()
            g.append(np.max(np.abs(tm - th)) / np.max(np.abs(th)))
        gaps.append(g)
    order = np.polyfit(np.log(eps), np.log(np.max(gaps, axis=0)), 1)[0]
    assert order > 0.9
    assert np.max(gaps) < 0.1


def test_gent_tends_to_neo_hookean():
    lt = np.array([1.5, 2.0, 3.0, 0.8])
    lp = np.array([1.2, 0.9, 1.5, 1.3])
    nh = np.array(_t(NeoHookean(), lt, lp))
    jms = np.array([1e2, 1e3, 1e4, 1e5])
    diffs = [np.max(np.abs(np.array(_t(Gent(jm=j), lt, lp)) - nh)) for j in jms]
    order = -np.polyfit(np.log(jms), np.log(diffs), 1)[0]
    assert 0.95 < order < 1.05  # the gap is O(1/J_m)
    assert diffs[-1] < 1e-3


def test_mooney_rivlin_c2_zero_is_neo_hookean():
    lt = np.linspace(0.7, 4.0, 9)
    lp = np.linspace(1.3, 0.8, 9)
    np.testing.assert_allclose(
        _t(MooneyRivlin(c1=0.5, c2=0.0), lt, lp), _t(NeoHookean(), lt, lp), rtol=0, atol=1e-13
    )


L = np.array([1.1, 1.5, 2.0, 3.0, 4.5])


def _uniaxial(mat):
    return _t(mat, L, L**-0.5)


@pytest.mark.parametrize(
    "mat, sigma",
    [
        (NeoHookean(), lambda l: l**2 - 1 / l),
        (MooneyRivlin(c1=0.3, c2=0.2), lambda l: 2 * (0.3 + 0.2 / l) * (l**2 - 1 / l)),
        (Gent(jm=50.0), lambda l: (l**2 - 1 / l) / (1 - (l**2 + 2 / l - 3) / 50.0)),
    ],
    ids=["neo_hookean", "mooney_rivlin", "gent"],
)
def test_uniaxial_closed_form(mat, sigma):
    """Uniaxial tension: T = sigma * h / h0 with h/h0 = l^-1/2 and T_phi = 0 at the natural
    width."""
    tt, tp = _uniaxial(mat)
    np.testing.assert_allclose(tt, sigma(L) * L**-0.5, rtol=1e-12)
    np.testing.assert_allclose(tp, 0.0, atol=1e-12)


def test_hookean_uniaxial_closed_form():
    w = 1 - (L - 1) / 2
    tt, tp = _t(Hookean(), L[:3], w[:3])
    np.testing.assert_allclose(
        tt, 3 * (L[:3] - 1) / w[:3], rtol=1e-12
    )  # E = 3G, per deformed length
    np.testing.assert_allclose(tp, 0.0, atol=1e-12)


@pytest.mark.parametrize(
    "mat, sigma",
    [
        (NeoHookean(), lambda l: l**2 - l**-4),
        (MooneyRivlin(c1=0.3, c2=0.2), lambda l: 2 * (0.3 + 0.2 * l**2) * (l**2 - l**-4)),
        (Gent(jm=50.0), lambda l: (l**2 - l**-4) / (1 - (2 * l**2 + l**-4 - 3) / 50.0)),
        (Hookean(), lambda l: 6 * (l - 1) * l),  # 2 (2a + a) = 6a per reference length; h/h0 = l^-2
    ],
    ids=["neo_hookean", "mooney_rivlin", "gent", "hookean"],
)
def test_equibiaxial_closed_form(mat, sigma):
    """Equibiaxial tension: T_theta = T_phi = sigma * l^-2 (sigma the Cauchy stress)."""
    lam = L[:4]
    tt, tp = _t(mat, lam, lam)
    np.testing.assert_allclose(tt, sigma(lam) * lam**-2, rtol=1e-12)
    np.testing.assert_allclose(tp, tt, rtol=1e-12)


def test_gent_limit_is_a_clear_error():
    gent = Gent(jm=50.0)
    lock = gent.max_uniaxial_stretch()
    assert abs(lock**2 + 2 / lock - 53.0) < 1e-9  # I1 = J_m + 3 in uniaxial tension
    with pytest.raises(MaterialRangeError, match="outside"):
        check_range(gent, [lock * 1.01], [lock**-0.5])
    # the static model's public check (unrelaxed energy): 5.2 equibiaxial is past the lock
    with pytest.raises(MaterialRangeError, match="J_m"):
        check_static_range(gent, [5.2, 1.0], [5.2, 1.0])
    check_static_range(gent, [5.1, 1.0], [5.1, 1.0])  # just inside


def _subclasses(cls):
    for sub in cls.__subclasses__():
        yield sub
        yield from _subclasses(sub)


def test_methods_are_abstract_or_final():
    """The equinox pattern: no material overrides a concrete method of a class above it."""
    import inspect

    from dynslip.physics.materials import AbstractMaterial

    bad = []
    for cls in _subclasses(AbstractMaterial):
        if not cls.__module__.startswith("dynslip."):
            continue
        for name, member in vars(cls).items():
            if name.startswith("__") or not callable(member):
                continue
            for base in cls.__mro__[1:]:
                inherited = vars(base).get(name)
                if inherited is not None and not getattr(inherited, "__isabstractmethod__", False):
                    bad.append(f"{cls.__name__}.{name} overrides {base.__name__}.{name}")
                    break
        assert not inspect.isabstract(cls) or cls.__name__.startswith("Abstract"), cls
    assert not bad, bad
