"""The figure of ``dynslip compare``: end states on their contact regions and the
difference to the first run (:mod:`dynslip.analysis.compare`)."""

from __future__ import annotations

import textwrap

from dynslip.analysis.compare import difference, trapped_text
from dynslip.data.files import save_figure
from dynslip.plot.style import pyplot

__all__ = ["plot_compare"]


def _short(name: str) -> str:
    """A run's name in a legend: its folder's name, wrapped (the table prints it whole)."""
    from pathlib import Path

    p = Path(name)
    return "\n".join(textwrap.wrap((p.parent.name if p.suffix == ".nc" else p.name) or name, 40))


def plot_compare(states: dict, path):
    """Draw the end states (name -> :func:`~dynslip.analysis.compare.end_state`, the first
    the reference) and their differences, save the figure to ``path``; returns the path."""
    plt = pyplot()

    names = list(states)
    ref = states[names[0]]
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(10, 5), constrained_layout=True)
    for n in names:
        s = states[n]
        ax0.plot(
            s["rbar"][s["contact"]],
            s["theta"][s["contact"]],
            label=f"{_short(n)}\ntrapped: {trapped_text(s.get('trapped'))}; "
            f"theta_max {s['theta_max']:.3g} rad; mu_mob. max {s['mu_mobilised_max']:.3g}",
        )
    ax0.set_xlabel(r"$\bar r$ (material radius / R)")
    ax0.set_ylabel(r"$\theta$ (rad)")
    ax0.set_title("end states on the contact region")
    ax0.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.14), frameon=False)
    for n in names[1:]:
        d = difference(ref, states[n])
        ax1.plot(d["rbar"], d["dtheta"], label=f"{_short(names[0])} - {_short(n)}")
    ax1.axhline(0, color="0.6", lw=0.8)
    ax1.set_xlabel(r"$\bar r$")
    ax1.set_ylabel(r"$\Delta\theta$ (rad)")
    ax1.set_title("difference on the common contact region")
    ax1.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.14), frameon=False)
    path = save_figure(fig, path, dpi=120)
    plt.close(fig)
    return path
