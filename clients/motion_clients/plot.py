"""A PNG of a trace, laid out like the operation waveforms in the seeds: positions on top
(as displacements from the first sample, labelled with it), velocities below, other
signals (status bits, states) in a third panel when present.

matplotlib is the ``plot`` extra; it is imported here only, with the file-only Agg backend.
"""

from __future__ import annotations

from pathlib import Path

from .trace import CLOCK_COLUMNS, Trace

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def panels(trace: Trace) -> dict[str, list[str]]:
    """Columns by panel: ``position`` (…Position), ``velocity`` (…Velocity), ``signals``."""
    out: dict[str, list[str]] = {"position": [], "velocity": [], "signals": []}
    for name in trace.columns:
        if name in CLOCK_COLUMNS:
            continue
        if name.endswith("Position") or name.endswith("FeedbackInput"):
            out["position"].append(name)
        elif name.endswith("Velocity"):
            out["velocity"].append(name)
        else:
            out["signals"].append(name)
    return {k: v for k, v in out.items() if v}


def plot_trace(trace: Trace, path: str | Path, title: str = "") -> Path:
    """Draw ``trace`` into the PNG ``path`` (its folder is created)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = panels(trace)
    if not groups:
        raise ValueError("the trace has no tag columns to plot")
    time = trace.column("time")
    t0 = time[0] if time else 0.0
    t = [x - t0 for x in time]
    fig, axes = plt.subplots(len(groups), 1, sharex=True, figsize=(9, 2.6 * len(groups) + 0.8))
    axes_list = list(axes) if len(groups) > 1 else [axes]
    labels = {"position": "displacement", "velocity": "velocity", "signals": "signals"}
    for ax, (kind, names) in zip(axes_list, groups.items(), strict=True):
        for name in names:
            units = trace.units.get(name, "")
            label = f"{name} [{units}]" if units else name
            values = trace.column(name)
            if kind == "signals":
                ax.step(t, values, where="post", label=label)
            elif kind == "position" and values:
                # displacement from the first sample: the motion's shape at any offset
                p0 = values[0]
                ax.plot(t, [v - p0 for v in values], label=f"{label} − {p0:.6g}")
            else:
                ax.plot(t, values, label=label)
        ax.set_ylabel(labels[kind])
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    axes_list[-1].set_xlabel(f"time [s] from {t0:.3f} s")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def is_png(path: str | Path) -> bool:
    """True when ``path`` starts with the PNG signature and holds an IHDR chunk."""
    head = Path(path).read_bytes()[:16]
    return head[:8] == PNG_SIGNATURE and head[12:16] == b"IHDR"
