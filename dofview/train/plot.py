"""A training run's loss and Gaussian count over time, as a PNG (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

from dofview.errors import DofviewError
from dofview.io.atomic import atomic_output


def plot_history(rows: list[dict], path: str | Path, title: str = "") -> None:
    """Loss (log scale, left) and Gaussian count (right) against step; warm-up shaded."""
    try:
        import matplotlib
    except ModuleNotFoundError:
        raise DofviewError(f"{path}: plotting needs matplotlib (pip install matplotlib)") from None

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = [r["step"] for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=100)
    ax.plot(steps, [r["loss"] for r in rows], color="tab:blue")
    ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_ylabel("mean loss since the last point", color="tab:blue")
    warm = [r["step"] for r in rows if r["stage"] == "warm-up"]
    if warm:
        ax.axvspan(0, max(warm), color="0.9", label="warm-up (aligned, pinhole)")
        ax.legend(loc="upper center", fontsize=8)
    count = ax.twinx()
    count.plot(steps, [r["gaussians"] for r in rows], color="tab:orange")
    count.set_ylabel("Gaussians", color="tab:orange")
    ax.set_title(title or "training")
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
