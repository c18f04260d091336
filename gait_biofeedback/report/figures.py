"""The report's plots as SVG text (matplotlib, text drawn as paths so the PDF shows the same glyphs).
Degrees only here, for display."""

from __future__ import annotations

import io
import math
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from gait_biofeedback.core.biofeedback import normative
from gait_biofeedback.core.biofeedback.evaluator import SAGITTAL
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.report.analysis import SessionAnalysis
from gait_biofeedback.report.extract import SessionData

plt.rcParams.update(
    {
        "svg.fonttype": "path",
        "font.size": 8,
        "axes.titlesize": 9,
        "figure.dpi": 100,
        "svg.hashsalt": "gait_biofeedback",
    }
)
SIDE_COLOUR = {"left": "#c0392b", "right": "#2471a3"}
POSTURES = {0: "unknown", 1: "standing", 2: "sitting", 3: "lying"}
LOCOMOTION = {0: "none", 1: "level", 2: "upstairs", 3: "downstairs"}
TRANSITIONS = {1: "sit→stand", 2: "stand→sit", 3: "sit→lie", 4: "lie→sit", 5: "stand→lie", 6: "lie→stand"}


def _svg(fig) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    plt.close(fig)
    text = buf.getvalue()
    return re.sub(r"<metadata>.*?</metadata>", "", text[text.index("<svg") :], flags=re.S)


def joint_curves(analysis: SessionAnalysis, tolerance: dict[str, float],
                 toe_off: dict[str, float] | None = None) -> str:
    """Hip, knee and ankle (rows) per side (columns): mean ± SD over the strides on the reference band;
    the initial contacts at 0 and 100 %, ``toe_off`` (side → % of the stride) marked TC."""
    pct = analysis.percent
    toe_off = toe_off or {}
    fig, axes = plt.subplots(3, 2, figsize=(7.2, 4.6), sharex=True)
    for col, side in enumerate(SIDES):
        for row, name in enumerate(SAGITTAL):
            ax = axes[row][col]
            mean, low, high = normative.reference_band(name, tolerance[name], pct)
            ax.fill_between(
                pct,
                np.degrees(low),
                np.degrees(high),
                color="#bbbbbb",
                alpha=0.5,
                lw=0,
                label="reference ± tolerance",
            )
            ax.plot(pct, np.degrees(mean), color="#777777", lw=0.8, ls="--")
            curves = analysis.curves[side][name]
            if len(curves):
                m, s = np.degrees(curves.mean(axis=0)), np.degrees(curves.std(axis=0))
                ax.fill_between(pct, m - s, m + s, color=SIDE_COLOUR[side], alpha=0.25, lw=0)
                ax.plot(pct, m, color=SIDE_COLOUR[side], lw=1.4, label=f"{side}, mean ± SD ({len(curves)})")
            else:
                ax.text(50, 0, "no strides with angles", ha="center", va="center")
            ax.set_title(f"{side} {name.replace('_', ' ')}")
            ax.grid(alpha=0.3)
            marks = [(0.0, "IC"), (100.0, "IC")]
            if math.isfinite(toe_off.get(side, math.nan)):
                marks.append((toe_off[side], "TC"))
            for x, label in marks:
                ax.axvline(x, color="k", lw=0.6, ls=":")
                ax.text(x, 1.0, label, transform=ax.get_xaxis_transform(), ha="center", va="bottom",
                        fontsize=6)
            if col == 0:
                ax.set_ylabel("deg")
            if row == 2:
                ax.set_xlabel("% of stride (IC to IC)")
    handles: dict[str, object] = {}
    for ax in axes[0]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    fig.legend(list(handles.values()), list(handles), loc="upper center", ncol=3, fontsize=7, frameon=False)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.95))  # the legend above the panels, outside the data
    return _svg(fig)


def movement_analysis_profile(analysis: SessionAnalysis) -> str:
    """Gait Variable Scores per variable and side, and the GPS (Baker et al. 2009), in degrees."""
    labels = [n.replace("_", " ") for n in SAGITTAL] + ["GPS"]
    fig, ax = plt.subplots(figsize=(7.2, 2.2))
    x = np.arange(len(labels))
    for k, side in enumerate(SIDES):
        values = [analysis.gvs[side].get(n, math.nan) for n in SAGITTAL] + [analysis.gps[side]]
        bars = ax.bar(x + (k - 0.5) * 0.38, np.degrees(values), 0.36, color=SIDE_COLOUR[side], label=side)
        for b, v in zip(bars, values, strict=True):
            if math.isfinite(v):
                ax.text(
                    b.get_x() + b.get_width() / 2,
                    b.get_height(),
                    f"{math.degrees(v):.1f}",
                    ha="center",
                    va="bottom",
                    fontsize=7,
                )
    ax.set_xticks(x, labels)
    ax.set_ylabel("deg (RMS from reference)")
    ax.legend(frameon=False, fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))  # beside the bars
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return _svg(fig)


def strides_over_time(data: SessionData, analysis: SessionAnalysis) -> str:
    """Stride time and stride length of every stride (used: filled; left out: hollow)."""
    fig, axes = plt.subplots(2, 1, figsize=(7.2, 2.8), sharex=True)
    used = {(r["side"], r["stride_index"]) for r in analysis.used}
    for side in SIDES:
        rows = [r for r in data.strides if r["side"] == side]
        for ax, name, scale, unit in (
            (axes[0], "stride_time", 1.0, "s"),
            (axes[1], "stride_length", 1.0, "m"),
        ):
            on = [r for r in rows if (side, r["stride_index"]) in used]
            off = [r for r in rows if (side, r["stride_index"]) not in used]
            ax.plot(
                [r["end_s"] for r in on],
                [scale * r[name] for r in on],
                "o",
                ms=3,
                color=SIDE_COLOUR[side],
                label=f"{side} ({len(on)} used)",
            )
            ax.plot(
                [r["end_s"] for r in off],
                [scale * r[name] for r in off],
                "o",
                ms=3,
                mfc="none",
                color=SIDE_COLOUR[side],
                label=f"{side} left out ({len(off)})",
            )
            ax.set_ylabel(f"{name.replace('_', ' ')} ({unit})")
            ax.grid(alpha=0.3)
    top = 3.0  # plausible strides are 0.4-3 s
    for line in axes[0].lines:  # a longer one (a pause) as a triangle at the top: the PDF's SVG has no clip
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        over = y > top
        if over.any():
            line.set_data(x[~over], y[~over])
            axes[0].plot(x[over], np.full(over.sum(), 0.97 * top), "^", ms=3, mfc=line.get_mfc(),
                         color=line.get_color())
    axes[0].set_ylim(0, top)
    axes[1].set_ylim(bottom=0)
    axes[0].legend(fontsize=6, frameon=False, ncol=4, loc="lower left", bbox_to_anchor=(0.0, 1.0),
                   borderaxespad=0.0)  # above the plot, outside the data
    axes[1].set_xlabel("time into the session (s)")
    for a, b in analysis.walking_bouts or []:
        for ax in axes:
            ax.axvspan(a, b, color="#2ecc71", alpha=0.08, lw=0)
    fig.tight_layout()
    return _svg(fig)


def activity_timeline(data: SessionData) -> str:
    """Posture and locomotion over time, the transitions, and the step count."""
    fig, (ax, steps) = plt.subplots(
        2, 1, figsize=(7.2, 2.2), sharex=True, gridspec_kw={"height_ratios": [2, 1]}
    )
    if not data.activity:
        ax.text(0.5, 0.5, "no activity/state in this recording", ha="center", transform=ax.transAxes)
        return _svg(fig)
    t = np.array([a[0] for a in data.activity])
    end = max(float(t[-1]), data.duration_s)
    for row, (index, names, colours) in enumerate(
        (
            (1, POSTURES, {0: "#dddddd", 1: "#5dade2", 2: "#f5b041", 3: "#af7ac5"}),
            (2, LOCOMOTION, {0: "#ffffff", 1: "#58d68d", 2: "#f1948a", 3: "#85c1e9"}),
        )
    ):
        values = [a[index] for a in data.activity]
        k = 0
        while k < len(values):
            j = k
            while j + 1 < len(values) and values[j + 1] == values[k]:
                j += 1
            stop = t[j + 1] if j + 1 < len(t) else end
            ax.broken_barh(
                [(t[k], stop - t[k])], (1 - row - 0.4, 0.8), color=colours.get(values[k], "#999999")
            )
            if stop - t[k] > 0.06 * end:
                ax.text(
                    (t[k] + stop) / 2,
                    1 - row,
                    names.get(values[k], "?"),
                    ha="center",
                    va="center",
                    fontsize=7,
                )
            k = j + 1
    last_label, level = -math.inf, 0
    for when, code in data.transitions:  # labels close together stacked, not overlapping
        level = (level + 1) % 3 if when - last_label < 0.08 * end else 0
        last_label = when
        ax.axvline(when, color="k", lw=0.8)
        ax.text(when, 1.45 + 0.3 * level, TRANSITIONS.get(code, "?"), fontsize=6, ha="center")
    ax.set_yticks([1, 0], ["posture", "locomotion"])
    ax.set_ylim(-0.6, 2.2)
    steps.step(t, [a[3] for a in data.activity], where="post", color="k", lw=1)
    steps.set_ylabel("steps")
    steps.set_xlabel("time into the session (s)")
    steps.grid(alpha=0.3)
    fig.tight_layout()
    return _svg(fig)


def progress_plots(labels: list[str], panels: list[tuple[str, str, list[float]]]) -> str:
    """One panel per (title, unit, value per session), the sessions in order along x."""
    cols = 2
    rows = max(1, math.ceil(len(panels) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(7.2, 2.0 * rows), squeeze=False)
    for ax, (title, unit, values) in zip(axes.flat, panels, strict=False):
        ax.plot(range(len(labels)), values, "o-", color="k", ms=3)
        finite = [v for v in values if math.isfinite(v)]
        if all(v >= 0 for v in finite):  # the full range from 0, not a truncated axis
            ax.set_ylim(0, 1.15 * max(finite, default=1.0) or 1.0)
        ax.set_xticks(range(len(labels)), labels, rotation=20, fontsize=6)
        ax.set_title(title)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(panels) :]:
        ax.set_visible(False)
    fig.tight_layout()
    return _svg(fig)
