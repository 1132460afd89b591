"""`netcfg verify --report DIR`: per message the period and response histograms with the analysed bounds drawn in,
per bus the load over time against the analysed utilisation. PNGs without a timestamp: the same report gives the
same files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["draw"]


def draw(report: dict[str, Any], folder: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    written: list[str] = []

    def save(fig: Any, name: str) -> None:
        fig.tight_layout()
        path = folder / f"{name}.png"
        fig.savefig(path, metadata={"Software": None})
        plt.close(fig)
        written.append(str(path))

    for m in report["messages"]:
        hist = m["histograms"]
        if hist["period"] is not None:
            fig, ax = plt.subplots(figsize=(6, 3.2))
            _bars(ax, hist["period"], scale=1000)
            nominal = m["nominal_period_us"]
            if nominal is not None:
                slack = m["analysed_jitter_us"] or 0.0
                ax.axvline(nominal / 1000, color="#303030", linewidth=1, label="period")
                ax.axvspan((nominal - slack) / 1000, (nominal + slack) / 1000, color="#c03030", alpha=0.15,
                           label="analysed jitter")
                ax.legend()
            ax.set_xlabel("interval between frames, ms")
            ax.set_ylabel("frames")
            ax.set_title(f"{m['name']}: period")
            save(fig, f"period_{m['name']}")
        if hist["response"] is not None:
            fig, ax = plt.subplots(figsize=(6, 3.2))
            _bars(ax, hist["response"], scale=1)
            if m["wcrt_us"] is not None:
                ax.axvline(m["wcrt_us"], color="#c03030", linestyle="--", label="analysed worst case")
                ax.legend()
            ax.set_xlabel(f"response after {m['response_from'].upper()}, us")
            ax.set_ylabel("frames")
            ax.set_title(f"{m['name']}: response")
            save(fig, f"response_{m['name']}")
    for b in report["buses"]:
        load = b["load_per_window"]
        if not load:
            continue
        window_s = report["window_us"] / 1e6
        fig, ax = plt.subplots(figsize=(7, 3.2))
        times = [(i + 0.5) * window_s for i in range(len(load))]
        ax.plot(times, [100 * x for x in load], color="#4878a8", linewidth=1, label="measured")
        ax.axhline(100 * b["utilization_analysed"], color="#303030", linestyle=":", label="analysed utilisation")
        ax.axhline(100 * b["window_bound"], color="#c03030", linestyle="--", label="analysed bound per window")
        ax.set_xlabel("time from the first frame, s")
        ax.set_ylabel(f"load per {window_s * 1000:g} ms window, %")
        ax.set_title(f"bus {b['name']}: load")
        ax.legend(fontsize="small")
        save(fig, f"load_{b['name']}")
    return written


def _bars(ax: Any, hist: dict[str, Any], scale: float) -> None:
    """The fixed bins; frames beyond the last are counted in a note (the table has the extremes)."""
    edges = [e / scale for e in hist["edges_us"]]
    counts = hist["counts"][1:-1]
    ax.stairs(counts, edges, fill=True, color="#4878a8")
    beyond = hist["counts"][-1]
    if beyond:
        ax.text(0.99, 0.5, f"{beyond} beyond ->", transform=ax.transAxes, ha="right", color="#c03030")
