#!/usr/bin/env python3
"""Draw the body a recording's ``/tf`` places: a 3D stick figure at a few instants, as a PNG.

The frames are read back with ``mcap-ros2-support`` (not the project's reader) and composed here down
their tree (parent → child: p_child = p_parent + R_parent t, q_child = q_parent ⊗ q): what Foxglove's
3D panel does with the same messages. Each segment is drawn from its frame's origin to its distal end
(thigh and shank along their −y, the foot to the toes, the chest up its y), so a misplaced frame shows.

    .venv/bin/python scripts/plot_body_frames.py BAG -o /tmp/body.png [--at 40 41 42 ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

THIGH, SHANK, FOOT, ANKLE, TRUNK = 0.42, 0.43, 0.14, 0.08, 0.45  # the default body dimensions, m
END = {"chest": (0.0, TRUNK, 0.0), "left_thigh": (0.0, -THIGH, 0.0), "right_thigh": (0.0, -THIGH, 0.0),
       "left_shank": (0.0, -SHANK, 0.0), "right_shank": (0.0, -SHANK, 0.0),
       "left_foot": (FOOT, -ANKLE, 0.0), "right_foot": (FOOT, -ANKLE, 0.0)}


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    w, u = q[0], q[1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pw, pv, qw, qv = p[0], p[1:], q[0], q[1:]
    return np.concatenate([[pw * qw - pv @ qv], pw * qv + qw * pv + np.cross(pv, qv)])


def read_tf(bag: Path) -> list[tuple[int, Frames]]:
    """[(stamp ns, child → (parent, translation, rotation w, x, y, z))] of every /tf message."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    files = sorted(bag.glob("*.mcap")) if bag.is_dir() else [bag]
    out = []
    for file in files:
        with open(file, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for _, _, _, msg in reader.iter_decoded_messages(topics=["/tf"]):
                frames = {}
                for t in msg.transforms:
                    tr, r = t.transform.translation, t.transform.rotation
                    frames[t.child_frame_id] = (t.header.frame_id, np.array([tr.x, tr.y, tr.z]),
                                                np.array([r.w, r.x, r.y, r.z]))
                stamp = msg.transforms[0].header.stamp
                out.append((stamp.sec * 1_000_000_000 + stamp.nanosec, frames))
    return out


Frames = dict[str, tuple[str, np.ndarray, np.ndarray]]


def world_of(frames: Frames) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """child → (position, orientation) in ``world``, composed down the tree."""
    world: dict[str, tuple[np.ndarray, np.ndarray]] = {"world": (np.zeros(3), np.array([1.0, 0, 0, 0]))}
    pending = dict(frames)
    while pending:
        ready = [c for c, (parent, _, _) in pending.items() if parent in world]
        if not ready:
            break
        for child in ready:
            parent, t, q = pending.pop(child)
            p0, q0 = world[parent]
            world[child] = (p0 + _rotate(q0, t), _multiply(q0, q))
    return world


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bag")
    parser.add_argument("-o", "--output", required=True)
    parser.add_argument("--at", type=float, nargs="+", help="seconds after the first /tf (default: 6 over a "
                        "stride, 20 s into the frames)")
    args = parser.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    messages = read_tf(Path(args.bag))
    if not messages:
        raise SystemExit(f"{args.bag}: no /tf")
    t0 = messages[0][0]
    stamps = np.array([s for s, _ in messages])
    at = args.at or [20.0 + 0.18 * k for k in range(6)]
    fig = plt.figure(figsize=(3.2 * len(at), 4.6))
    for k, seconds in enumerate(at):
        i = int(np.argmin(np.abs(stamps - (t0 + seconds * 1e9))))
        world = world_of(messages[i][1])
        ax = fig.add_subplot(1, len(at), k + 1, projection="3d")
        for segment, end in END.items():
            if segment in world:
                p, q = world[segment]
                e = p + _rotate(q, np.array(end))
                side = segment.split("_")[0]
                colour = {"left": "tab:blue", "right": "tab:red"}.get(side, "black")
                ax.plot(*zip(p, e, strict=True), color=colour, lw=3)
        if "pelvis" in world:
            hips = [world[s][0] for s in ("left_thigh", "right_thigh") if s in world]
            if len(hips) == 2:
                ax.plot(*zip(*hips, strict=True), color="black", lw=3)
            x0, y0 = world["pelvis"][0][:2]
            ax.set_xlim(x0 - 0.6, x0 + 0.6)
            ax.set_ylim(y0 - 0.6, y0 + 0.6)
        ax.set_zlim(0.0, 1.5)
        ax.set_box_aspect((1.2, 1.2, 1.5))
        if "pelvis" in world:  # seen from the subject's right side: walking goes left to right
            right = _rotate(world["pelvis"][1], np.array([0.0, 0.0, 1.0]))
            ax.view_init(elev=8, azim=float(np.degrees(np.arctan2(right[1], right[0]))))
        ax.set_title(f"{(messages[i][0] - t0) / 1e9:.2f} s", fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y")
        ax.set_zlabel("z")
    fig.suptitle(f"{args.bag}: /tf composed (left blue, right red; z up, ground z = 0)", fontsize=9)
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)
    print(f"wrote {args.output}: {len(at)} instants of {len(messages)} /tf messages")


if __name__ == "__main__":
    main()
