"""Render one frame of FlagellumSteer-v0 for the docs (docs/figures/env_frame.png).

A seeded random path; the swimmer cruises at the low speed, then holds the high speed until
the flagellum buckles (or --max-steps), so the frame shows a buckled flagellum and a turn.

    python scripts/render_env_frame.py [--out docs/figures/env_frame.png] [--seed 3]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.image import imsave
from tqdm import tqdm

from flagellum_env.steer_env import FlagellumSteerEnv


def render_frame(seed: int = 3, cruise_steps: int = 3, max_steps: int = 20, **env_kwargs) -> np.ndarray:
    """The frame after ``cruise_steps`` at the low speed and high speed until buckled, (H, W, 3) uint8."""
    env = FlagellumSteerEnv(render_mode="rgb_array", **env_kwargs)
    env.reset(seed=seed)
    for k in tqdm(range(max_steps), unit="step"):
        action = np.array([-1.0 if k < cruise_steps else 1.0], np.float32)
        _, _, terminated, truncated, info = env.step(action)
        if terminated or truncated or info["end_to_end_ratio"] < 0.6:
            break
    frame = env.render()
    env.close()
    return frame


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/figures/env_frame.png"))
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--cruise-steps", type=int, default=3, help="steps at the low speed first")
    ap.add_argument("--max-steps", type=int, default=20, help="at most this many steps in all")
    args = ap.parse_args(argv)
    frame = render_frame(args.seed, args.cruise_steps, args.max_steps)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    imsave(args.out, frame)
    print(f"wrote {args.out} ({frame.shape[1]} x {frame.shape[0]} px)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
