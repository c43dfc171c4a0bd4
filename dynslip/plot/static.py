"""Figures of the static scenarios; every function reads a dataset only.

- :func:`figure4_row`: the paper's Fig. 4 row for one model: theta vs rbar, both
  stretches, F_m, with the background coloured by the direction of friction;
- :func:`figure4`: the whole 3x3 Fig. 4 (Hookean, neo-Hookean, Gent);
- :func:`family_plot`: mu across the fully mobilised family;
- :func:`cylinder_plot`: the 2D capstan bounds and vertical force;
- :func:`save_figure4_row`, :func:`save_figure4`, :func:`save_family`,
  :func:`save_cylinder`: draw one of them and save it to the path given (the runners
  name the path; nothing else is written).
"""

from __future__ import annotations

import numpy as np

from dynslip.data.files import save_figure
from dynslip.plot.style import MODEL_LABELS as LABEL
from dynslip.plot.style import pyplot

__all__ = [
    "figure4_row",
    "figure4",
    "family_plot",
    "cylinder_plot",
    "save_figure4_row",
    "save_figure4",
    "save_family",
    "save_cylinder",
]

C_EQ, C_POLE = "#fde0c5", "#cfe3f5"  # friction toward the equator / toward the pole


def _background(ax, rbar, direction):
    """Shade spans of rbar by the direction of friction (+1 toward the equator, -1 toward the
    pole)."""
    edges = np.concatenate([[rbar[0]], 0.5 * (rbar[1:] + rbar[:-1]), [rbar[-1]]])
    for i, d in enumerate(direction):
        if d != 0:
            ax.axvspan(edges[i], edges[i + 1], color=C_EQ if d > 0 else C_POLE, lw=0, zorder=0)


def _row(axes, ds, title: str):
    r = ds["rbar"].values
    direction = ds["friction_direction"].values
    for ax in axes:
        _background(ax, r, direction)
        ax.set_xlim(r[0], r[-1])
        ax.set_xlabel(r"$\bar r$")
    a, b, c = axes
    a.plot(r, ds["theta"].values, "k-", lw=1.5, label="end state")
    a.plot(r, ds["theta_initial"].values, "C3--", lw=1, label="initial")
    a.set_ylabel(r"$\theta$ (rad)")
    a.legend(loc="lower right", fontsize=7)
    b.plot(r, ds["lambda_theta"].values, "C0-", label=r"$\lambda_\theta$")
    b.plot(r, ds["lambda_phi"].values, "C1-", label=r"$\lambda_\phi$")
    b.set_ylabel("stretch")
    b.legend(loc="upper right", fontsize=7)
    mu = float(ds["mu"].values)
    c.plot(r, ds["F_m"].values, "k-", label=r"$F_m$")
    c.plot(r, mu * ds["F_N"].values, "C2:", lw=1, label=r"$\pm\mu F_N$")
    c.plot(r, -mu * ds["F_N"].values, "C2:", lw=1)
    c.axhline(0, color="0.5", lw=0.5)
    c.set_ylabel(r"$F_m$ ($G h_0/R$)")
    c.legend(loc="upper right", fontsize=7)
    a.set_title(title, fontsize=9, loc="left")


def _title(ds, model: str) -> str:
    mu = float(ds["mu"].values)
    return f"{LABEL.get(model, model)}: $\\mu$ = {mu:.3f} (BVP {float(ds['mu_family'].values):.3f})"


def _legend(fig):
    from matplotlib.patches import Patch

    fig.legend(handles=[Patch(color=C_EQ, label="friction toward the equator"),
                        Patch(color=C_POLE, label="friction toward the pole")],
               loc="lower center", ncol=2, fontsize=8, frameon=False)


def figure4_row(ds):
    """One row of the paper's Fig. 4 from a ``static`` result dataset."""
    plt = pyplot()

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    _row(axes, ds, _title(ds, ds.attrs.get("model", "")))
    _legend(fig)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    return fig


def figure4(ds):
    """The 3x3 Fig. 4 from a ``figure4`` result dataset (dimension ``model``)."""
    plt = pyplot()

    models = [str(m) for m in ds["model"].values]
    fig, axes = plt.subplots(len(models), 3, figsize=(12, 3.2 * len(models)))
    for i, m in enumerate(models):
        sub = ds.isel(model=i)
        _row(axes[i], sub, _title(sub, m))
    _legend(fig)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    return fig


def family_plot(ds):
    """mu (and the switch angle) across the fully mobilised family, the selected members marked."""
    plt = pyplot()

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    x = ds["switch_value"].values
    xl = (
        "switch radius $\\bar r_s$ (R)"
        if ds.attrs.get("switch_by") == "switch_radius"
        else "switch angle (rad)"
    )
    for i, m in enumerate(ds["model"].values):
        m = str(m)
        line, = a.plot(x, ds["mu"].values[i], "-o", ms=3, label=LABEL.get(m, m))
        b.plot(ds["switch_theta"].values[i], ds["mu"].values[i], "-o", ms=3, color=line.get_color(),
               label=LABEL.get(m, m))
        sel = ds["switch_rbar_selected"].values[i] if ds.attrs.get("switch_by") == "switch_radius" \
            else ds["switch_theta_selected"].values[i]
        a.plot([sel], [ds["mu_selected"].values[i]], "*", ms=12, color=line.get_color(), mec="k")
        b.plot([ds["switch_theta_selected"].values[i]], [ds["mu_selected"].values[i]], "*", ms=12,
               color=line.get_color(), mec="k")
        pm = ds["mu_paper"].values[i]
        if np.isfinite(pm):
            for ax in (a, b):
                ax.axhline(pm, color=line.get_color(), ls=":", lw=1)
    a.set_xlabel(xl)
    a.set_ylabel(r"$\mu$")
    b.set_xlabel(r"switch angle $\theta_s$ = angle of the largest $\lambda_\theta$ (rad)")
    b.set_ylabel(r"$\mu$")
    a.legend(fontsize=8)
    a.set_title("fully mobilised family (stars: selected; dotted: paper)", fontsize=9, loc="left")
    b.axvline(np.pi / 4, color="0.5", lw=0.8, ls="--")
    b.text(np.pi / 4, b.get_ylim()[1], r" $\pi/4$", va="top", fontsize=8)
    fig.tight_layout()
    return fig


def cylinder_plot(ds):
    """Capstan bounds with random admissible tensions, and F_v against theta_max (all > 0)."""
    plt = pyplot()

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    th = ds["theta"].values
    for t in ds["T"].values:
        a.plot(th, t, color="0.6", lw=0.5)
    a.plot(th, ds["T_upper"].values, "C3-", lw=2, label=r"$T_0 e^{\mu\theta}$")
    a.plot(th, ds["T_lower"].values, "C0-", lw=2, label=r"$T_0 e^{-\mu\theta}$")
    a.set_yscale("log")
    a.set_xlabel(r"$\theta$ (rad)")
    a.set_ylabel(r"$T/T_0$")
    a.set_title(f"capstan bounds, $\\mu$ = {float(ds['mu'].values):.2f} (grey: admissible states)",
                fontsize=9, loc="left")
    a.legend(fontsize=8)
    tm = ds["theta_max"].values
    fv = ds["F_v"].values
    b.fill_between(
        tm, fv.min(axis=1), fv.max(axis=1), color="0.8", label="random admissible states"
    )
    b.plot(
        tm, ds["F_v_lower"].values, "C0-", label=r"$T_0 e^{-\mu\theta_m}\sin\theta_m$ (lower bound)"
    )
    b.axhline(0, color="k", lw=0.8)
    b.set_yscale("symlog", linthresh=1e-2)
    b.set_xlabel(r"$\theta_{max}$ (rad)")
    b.set_ylabel(r"$F_v/(R\,T_0)$")
    b.set_title("vertical force: always > 0 (no invagination in 2D)", fontsize=9, loc="left")
    b.legend(fontsize=8)
    fig.tight_layout()
    return fig


def save_figure4_row(ds, path):
    """:func:`figure4_row` of a ``static`` result saved to ``path``; returns the path."""
    return save_figure(figure4_row(ds), path, dpi=110)


def save_figure4(ds, path):
    """:func:`figure4` of a ``figure4`` result saved to ``path``; returns the path."""
    return save_figure(figure4(ds), path, dpi=100)


def save_family(ds, path):
    """:func:`family_plot` of a ``family`` result saved to ``path``; returns the path."""
    return save_figure(family_plot(ds), path, dpi=110)


def save_cylinder(ds, path):
    """:func:`cylinder_plot` of a ``cylinder`` result saved to ``path``; returns the path."""
    return save_figure(cylinder_plot(ds), path, dpi=110)
