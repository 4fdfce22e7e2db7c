#!/usr/bin/env python3
"""What any contact detection could save on a bed: pair tests per particle-step, counted.

Reads the frames of an am-sim run (written every few steps; `benches/detection_bound.sh` makes
them) and replays the run's motion between them to count, per particle-step, how many pair tests
four ways of finding the touching pairs need (docs/performance-log.md, forty-first and forty-sixth
rounds):

* **the floor**: only the touching pairs, which need their laws anyway, as an oracle would;
* **near lists** (what am-sim does, `neighbor::NearPairs`): at a refresh every candidate pair of
  the Verlet list is tested and those whose gap is below the near skin s are kept; between
  refreshes only those are tested. A pair left out had a gap of at least s, and each of its
  particles moved at most the step's largest displacement τ per step, so the lists are refreshed
  when 2 Σ τ reaches s. Printed for several s: near tests per particle-step, and candidate tests
  at the refreshes per particle-step;
* **per-entry thresholds**: each pair keeps, from its last test, the sum of its two particles'
  path lengths then plus its gap then, and is tested again only when the sum of the two path
  lengths reaches that threshold (every pair's own bound, not the bed's fastest particle's). Over
  every candidate pair, and inside the near lists of each s (the thresholds restarted at each
  refresh).
* **the bed's budget in the near lists**: each near entry keeps its gap at the refresh, and is
  tested only once 2 Σ τ since the refresh (the budget the lists are refreshed by) reaches it.
  The bound of any skip by the bed's fastest particle: no check per step or per pair counted,
  just the tests (forty-sixth round).

Between frames the positions are interpolated linearly, one step at a time, and each particle's
path length is the sum of its steps' displacements, so the bounds above hold exactly for the
replayed motion (frames every step and every fifth step gave the same counts on the 19.2k bed).
The candidates are the pairs within the radii's sum plus the Verlet skin at the first frame
(the list is built once in such a window on a bed at rest: check the run's summary).

usage: detection_bound.py FRAMES_H5 SCENE_TOML [--every N] [--skins S1,S2,...]
       detection_bound.py --self-test
"""

import argparse
import sys

import numpy as np


def minimum_image(separation, box):
    """Separations mapped to their nearest periodic image along the axes with a box length."""
    for axis, length in enumerate(box):
        if length:
            separation[..., axis] -= length * np.round(separation[..., axis] / length)
    return separation


def unwrap(positions, box):
    """Frames of positions with the periodic jumps taken out, so differences are displacements."""
    steps = minimum_image(np.diff(positions, axis=0), box)
    return np.concatenate([positions[:1], positions[:1] + np.cumsum(steps, axis=0)])


def candidate_pairs(position, radius, skin, box, chunk=512):
    """The pairs (i < j) whose gap is below `skin`: the Verlet list's candidates."""
    owners, partners = [], []
    for start in range(0, len(position), chunk):
        separation = minimum_image(position[None, :, :] - position[start:start + chunk, None, :], box)
        distance = np.sqrt((separation**2).sum(-1))
        reach = radius[start:start + chunk, None] + radius[None, :] + skin
        i, j = np.nonzero(distance < reach)
        i += start
        keep = i < j
        owners.append(i[keep])
        partners.append(j[keep])
    return np.concatenate(owners), np.concatenate(partners)


class Replay:
    """The motion between frames, one step at a time: positions and each particle's path length."""

    def __init__(self, frames, every, box):
        self.frames = unwrap(np.asarray(frames, dtype=float), box)
        self.every = every
        self.box = box
        self.steps = (len(self.frames) - 1) * every
        # Path length of each particle up to each step, and the step's largest displacement.
        path = np.zeros(self.frames.shape[1])
        self.path = [path]
        self.largest = np.empty(self.steps)
        previous = self.position(0)
        for step in range(1, self.steps + 1):
            current = self.position(step)
            moved = np.sqrt(((current - previous) ** 2).sum(-1))
            path = path + moved
            self.path.append(path)
            self.largest[step - 1] = moved.max()
            previous = current

    def position(self, step):
        frame, within = divmod(step, self.every)
        if within == 0:
            return self.frames[frame]
        return self.frames[frame] + (self.frames[frame + 1] - self.frames[frame]) * (within / self.every)


def gaps(replay, step, radius, owners, partners):
    """Gap (distance minus the radii's sum) of the given pairs at a step [m]: negative = touching."""
    position = replay.position(step)
    separation = minimum_image(position[partners] - position[owners], replay.box)
    return np.sqrt((separation**2).sum(-1)) - radius[owners] - radius[partners]


def count_tests(replay, radius, owners, partners, skins):
    """Pair tests of each way, summed over the replay's steps (see the module's docstring).

    For each near skin s: (refreshes, near tests, tests with per-entry thresholds in those lists,
    touching pairs met, tests by the bed's budget in those lists). An infinite s is every
    candidate, with its thresholds never restarted: the lists' only refresh is the first, which
    the candidates' own sift at the build stands for.
    Touching pairs are due at every step in every list, so each skin meets the same ones.
    """
    every_pair = np.arange(len(owners))
    counts = {}
    for skin in skins:
        near = None
        budget = 0.0
        refreshes = near_tests = threshold_tests = touching = budget_tests = 0
        for step in range(replay.steps):
            if near is None or budget >= skin:
                every_gap = gaps(replay, step, radius, owners, partners)
                near = every_pair[every_gap < skin]
                threshold = np.full(len(near), -np.inf)
                gap_then = every_gap[near]
                budget = 0.0
                refreshes += 1
            near_tests += len(near)
            # A pair whose gap at the refresh exceeds the budget since cannot touch yet.
            budget_tests += int((gap_then <= budget).sum())
            path = replay.path[step]
            due = path[owners[near]] + path[partners[near]] >= threshold
            tested = near[due]
            gap = gaps(replay, step, radius, owners[tested], partners[tested])
            threshold_tests += len(tested)
            touching += int((gap < 0).sum())
            threshold[due] = path[owners[tested]] + path[partners[tested]] + np.maximum(gap, 0.0)
            budget += 2.0 * replay.largest[step]
        counts[skin] = (refreshes, near_tests, threshold_tests, touching, budget_tests)
    return counts


def report(counts, particles, candidates, steps, near_cost, candidate_cost, check_cost):
    """Prints `counts` (count_tests, with an infinite skin for every candidate) per particle-step."""
    per = float(particles * steps)
    _, _, every_candidate_tests, touching, _ = counts[np.inf]
    floor = touching / per
    print(f"{particles} particles, {candidates} candidate pairs ({candidates / particles:.2f} per particle), "
          f"{steps} steps")
    print("pair tests per particle-step, and the sift's instructions at "
          f"{near_cost:g} per near test and {candidate_cost:g} per candidate at a refresh "
          f"(per-entry thresholds: {near_cost:g} per test and {check_cost:g} per check):")
    print(f"  the floor (touching pairs only):          {floor:.3f} tests, {near_cost * floor:.1f} instructions")
    tests = every_candidate_tests / per
    checks = candidates / particles
    print(f"  per-entry thresholds, every candidate:    {tests:.3f} tests, {checks:.2f} checks, "
          f"{near_cost * tests + check_cost * checks:.1f} instructions")
    print("  near skin [m]  refreshes  near tests  candidates tested  instructions"
          "  | per-entry thresholds in the near lists: tests  instructions"
          "  | the bed's budget: tests  instructions")
    for skin, (refreshes, near_tests, threshold_tests, _, budget_tests) in counts.items():
        if skin == np.inf:
            continue
        near = near_tests / per
        full = refreshes * candidates / per
        threshold = threshold_tests / per
        budget = budget_tests / per
        print(f"  {skin:13.3e}  {refreshes:9d}  {near:10.3f}  {full:17.3f}  "
              f"{near_cost * near + candidate_cost * full:12.1f}  "
              f"| {threshold:46.3f}  {near_cost * threshold + check_cost * near + candidate_cost * full:12.1f}"
              f"  | {budget:23.3f}  {near_cost * budget + candidate_cost * full:12.1f}")


def self_test():
    """Three spheres on the x axis whose tests are known in closed form.

    A and B touch and rest; C, at a gap g = 2.5 u from B, moves away by u per step (u = 2^-30 m,
    near skin s = 31 u). Every comparison below is decided by at least u/2, so the rounding of
    the interpolation between frames 5 steps apart cannot turn it.
    - Floor: A-B every step, T touching pairs met in T steps, by every way.
    - Per-entry thresholds: A-B every step; B-C at t = 0 and then when C has moved by the gap it
      had at its last test: t_{k+1} = 2 t_k + 3, so t = 0, 3, 9, 21, 45, 93 for T = 100.
    - Near lists: τ = u, refreshed when 2 u t reaches s, every 16 steps: 7 refreshes in 100 steps.
      B-C is near while its gap at a refresh is below 31 u: at t = 0 (2.5 u) and 16 (18.5 u), not
      at 32 (34.5 u); so T + 32 near tests. With thresholds in the lists, B-C is tested at t = 0,
      3, 9 and at the refresh at 16 (thresholds restart), next due at 16 + 18.5 = 34.5, after it
      has left: T + 4. By the bed's budget (2 u per step since the refresh), B-C is tested once
      2 u k reaches its gap then: at k ≥ 2 after t = 0 (2.5 u; steps 2-15) and k ≥ 10 after t = 16
      (18.5 u; steps 26-31): T + 20. Every candidate (one refresh): steps 2-99, T + 98.
    - A-C is beyond the Verlet skin (9e-6 m) and is no candidate.
    """
    u = 2.0**-30
    radius = np.full(3, 2.0**-16)
    steps = 100
    frames = np.zeros((steps + 1, 3, 3))
    frames[:, 1, 0] = 2 * radius[0] - 2.0**-24  # B overlaps A
    frames[:, 2, 0] = frames[0, 1, 0] + 2 * radius[0] + 2.5 * u + u * np.arange(steps + 1)
    box = (0.0, 0.0, 0.0)
    owners, partners = candidate_pairs(frames[0], radius, 9e-6, box)
    failures = []
    if sorted(zip(owners.tolist(), partners.tolist())) != [(0, 1), (1, 2)]:
        failures.append(f"candidates {list(zip(owners, partners))}, want A-B and B-C")
    for every in (1, 5):
        replay = Replay(frames[::every], every, box)
        # The motion is linear, so the interpolation between frames must give every step's place.
        if not all(np.allclose(replay.position(step), frames[step], rtol=0, atol=1e-18) for step in range(steps + 1)):
            failures.append(f"frames every {every} steps: the interpolated positions are not the motion's")
        counts = count_tests(replay, radius, owners, partners, [np.inf, 31 * u])
        # Every candidate: one refresh, both pairs' entries at every step (2 T).
        want = {
            np.inf: (1, 2 * steps, steps + 6, steps, steps + 98),
            31 * u: (7, steps + 32, steps + 4, steps, steps + 20),
        }
        if counts != want:
            failures.append(f"frames every {every} steps: counted {counts}, want {want}")
    # The periodic image: a pair across the box's edge is found and its gap measured through it.
    box = (1e-3, 0.0, 0.0)
    across = np.array([[1e-3 - 1e-5, 0.0, 0.0], [1e-5, 0.0, 0.0]])
    owners, partners = candidate_pairs(across, np.full(2, 1.1e-5), 9e-6, box)
    replay = Replay(np.repeat(across[None], 3, axis=0), 1, box)
    if len(owners) != 1 or not np.isclose(gaps(replay, 1, np.full(2, 1.1e-5), owners, partners)[0], -2e-6):
        failures.append("the pair across the periodic edge was not found with a gap of -2e-6 m")
    for failure in failures:
        print("self-test FAILED:", failure)
    if not failures:
        print("self-test passed: closed-form counts of thresholds, near lists and the bed's budget, frames "
              "every 1 and 5 steps, periodic images")
    return 1 if failures else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("frames", nargs="?", help="an am-sim HDF5 file with frames every few steps")
    parser.add_argument("scene", nargs="?", help="the scene that wrote it (skin, periodic box, output cadence)")
    parser.add_argument("--skins", default="2e-8,5e-8,1.3e-7,3e-7,1.125e-6",
                        help="near skins to replay [m] (am-sim's tuner chose about 1.3e-7 on the 19.2k bed)")
    parser.add_argument("--near-cost", type=float, default=38.0,
                        help="instructions per near-list test (fortieth round: 38)")
    parser.add_argument("--candidate-cost", type=float, default=68.0,
                        help="instructions per candidate tested at a refresh (twenty-sixth round: 68)")
    parser.add_argument("--check-cost", type=float, default=8.0,
                        help="instructions per threshold check (an estimate: two loads, an add, a compare, a branch)")
    parser.add_argument("--self-test", action="store_true", help="check the counting on closed-form cases")
    args = parser.parse_args()
    if args.self_test:
        return self_test()
    if not args.frames or not args.scene:
        parser.error("give FRAMES_H5 and SCENE_TOML, or --self-test")

    import tomllib

    import h5py

    with open(args.scene, "rb") as file:
        scene = tomllib.load(file)
    periodic = scene.get("periodic", {})
    box = tuple(
        (bounds[1] - bounds[0]) if bounds else 0.0
        for bounds in (periodic.get(f"{axis}_m") for axis in "xyz")
    )
    skin = scene["simulation"]["skin_m"]
    every = scene["output"]["every_steps"]

    with h5py.File(args.frames, "r") as file:
        frames, radius = [], None
        for name in sorted(file["frames"].keys()):
            frame = file["frames"][name]
            order = np.argsort(frame["id"][:])  # the store is sorted in space: follow the ids
            frames.append(frame["position"][:][order])
            if radius is None:
                radius = frame["radius"][:][order]
    replay = Replay(frames, every, box)
    owners, partners = candidate_pairs(replay.frames[0], radius, skin, box)
    skins = [float(value) for value in args.skins.split(",")]
    counts = count_tests(replay, radius, owners, partners, [np.inf] + skins)
    report(counts, len(radius), len(owners), replay.steps, args.near_cost, args.candidate_cost, args.check_cost)
    largest = replay.largest
    each = np.diff(np.array(replay.path), axis=0)
    print(f"largest displacement per step τ: median {np.median(largest):.3e} m; each particle's per step: "
          f"median {np.median(each):.3e} m, 99th percentile {np.percentile(each, 99):.3e} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
