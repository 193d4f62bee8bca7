"""Time one SELA step (GP update + fall model + UCB over the archive) and the toy experiment.

Run: ``.venv/bin/python benchmarks/bench_sela_step.py [--toy-replicates N]``.
Prints figures only; tests never assert on timings.
"""
import argparse
import subprocess
import sys
import tempfile
import time

from sela_ros import single_blas_thread

# One BLAS thread, as the nodes: on a shared, loaded machine OpenBLAS's threads for the
# (N, M) products cost 3-4x more than they save (20 ms vs 6 ms per step at 1e5 candidates).
single_blas_thread()

import numpy as np  # noqa: E402

from sela_ros.core.learning import SELA, PointMotion, observed_generic_reward  # noqa: E402
from sela_ros.core.learning.acquisition import learnt_error  # noqa: E402


def bench_step(num_candidates, observations=20, dim=8, repeats=15, seed=0):
    """(median, min) time of ask() + tell() with the given archive size after N observations.

    The min is the figure to quote on a shared, loaded machine.

    The planner is the straight line, so the time is the GP update plus UCB over all
    candidates (A* on a map is not included).
    """
    rng = np.random.default_rng(seed)
    candidates = rng.random((num_candidates, dim))
    prior = 0.1 * rng.normal(size=(num_candidates, 2))
    sela = SELA(candidates, prior, PointMotion(), goal=[2.0, 2.0])
    pose = np.zeros(2)
    for k in range(observations):
        d = sela.ask(pose)
        sela.tell(d.index, prior[d.index] + 0.01 * rng.normal(size=2))
        sela.tell_fall(d.index, k % 4 == 0)  # some falls: the fall-aware path is timed
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        d = sela.ask(pose)
        after = pose + prior[d.index] * 0.9
        sela.tell(d.index, observed_generic_reward(pose, after, sela.motion))
        sela.tell_fall(d.index, False)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times)), sela.gp.num_samples


def library_like(priors, count, seed=0):
    """``count`` tables made from the shipped ones (each a random mix of two, perturbed), for
    timing SELA with a library of that size before it is built."""
    from sela_ros.core.learning import DamagePriors

    rng = np.random.default_rng(seed)
    gr, fallen = priors.generic_reward, priors.fallen
    tables, falls = [], []
    for _ in range(count):
        i, j = rng.choice(len(priors), 2, replace=False)
        w = rng.random()
        tables.append(w * gr[i] + (1 - w) * gr[j] + 0.01 * rng.normal(size=gr[i].shape))
        falls.append(fallen[i] | fallen[j])
    return DamagePriors(tuple(f'synthetic:{k}' for k in range(count)), np.stack(tables),
                        np.stack(falls), priors.archive_checksum)


def bench_shipped(observations=20, repeats=15, seed=0, mixed=False, priors=None,
                  caution=None, mean_affine=None, progress=None, mean_descriptor=None,
                  hyper_sd=None, kernel_changes=None, reach=None, damage=None):
    """(median, min, gaits, prior in use, horizon) of one step on the shipped 8-D map, as the
    adapter runs it: SE(2) generic rewards, the fall GP and the support model of untried
    gaits, the shipped damage priors (the robot's steps are those of one of them, so the
    step is timed with a damage prior in use; ``mixed``: of two of them added up, from a
    standing start first, so the mixture of the tables is in use) and two steps ahead;
    ``caution``: ``acquisition.caution``, ``mean_affine``: ``gp.mean.affine``,
    ``progress``: ``acquisition.progress``; ``mean_descriptor``: ``gp.mean.descriptor`` (None:
    the defaults); ``hyper_sd``: ``gp.hyper.sd``, and ``kernel_changes`` (a list) is given
    ``(seconds, changed)`` of each step timed, ``changed`` whether the step changed the GP's
    kernel; ``reach``: ``acquisition.reach``; ``damage``: the robot's steps are those of
    this shipped table instead (a second-tier one: that tier in use). The last item
    returned says whether caution was on in the steps timed."""
    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.mission import make_sela
    from sela_ros.core.storage import default_archive_path, load_archive

    archive = load_archive(default_archive_path())
    shipped = resolve_priors('auto', default_archive_path(), archive.params)
    true = shipped.generic_reward[shipped.names.index(damage or 'remove:middle_right')]
    if mixed:
        other = shipped.generic_reward[shipped.names.index('remove:front_left')]
        true = true + other - archive.generic_reward
    if priors is None:
        priors = shipped
    elif isinstance(priors, int):
        priors = library_like(shipped, priors, seed)
    elif isinstance(priors, str):
        priors = resolve_priors(priors, default_archive_path(), archive.params)
    # One table chosen (priors.weights.sd none), or the tables mixed (the default).
    config = {} if mixed else {'priors.weights.sd': 'none'}
    if caution is not None:
        config['acquisition.caution'] = caution
    if mean_affine is not None:
        config['gp.mean.affine'] = mean_affine
    if progress is not None:
        config['acquisition.progress'] = progress
    if mean_descriptor is not None:
        config['gp.mean.descriptor'] = mean_descriptor
    if hyper_sd is not None:
        config['gp.hyper.sd'] = hyper_sd
    if reach is not None:
        config['acquisition.reach'] = reach
    sela = make_sela(archive, config or None, priors=priors)
    sela.set_goal([20.0, 20.0])  # far: every step plans two ahead
    rng = np.random.default_rng(seed)
    pose = np.zeros(3)
    for k in range(observations):
        d = sela.ask(pose)
        sela.tell(d.index, true[d.index] + 0.01 * rng.normal(size=3), standing_start=k == 0)
        # Some falls, the fall-aware path timed; with ``damage``, not the standing start,
        # which a second-tier table must reproduce to be used.
        sela.tell_fall(d.index, k % 4 == (1 if damage else 0))
    times = []
    for _ in range(repeats):
        kernel = sela.hyper
        t0 = time.perf_counter()
        d = sela.ask(pose)
        sela.tell(d.index, 0.9 * true[d.index])
        sela.tell_fall(d.index, False)
        times.append(time.perf_counter() - t0)
        if kernel_changes is not None:
            kernel_changes.append((times[-1], sela.hyper != kernel))
    limit = sela.config.acquisition_caution
    cautious = limit is not None and learnt_error(sela.state_dict()['surprises']) >= limit
    # Whether the affine map of the prior mean was in use in the steps timed (gp.mean.affine
    # is used only while it predicts the steps better than the prior mean as it is).
    mapped = sela.config.gp_mean_affine is not None and sela._affine_score > 0.0
    return (float(np.median(times)), float(np.min(times)), len(archive), d.prior,
            int(sela.config.planner_horizon), cautious, mapped)


def self_model_priors(pair='remove:front_left,remove:middle_left', seed=0):
    """``(priors, seconds, refine seconds)``: the shipped priors less ``pair`` (and its near
    duplicates, as the leave-one-out does) plus the self-model's table of it, made as the
    adapter makes it (:meth:`SelfModel.install`, its outcomes read off the pair's shipped
    table, which simulated them), then refined (the gaits it asks for next, those the pair's
    table simulated), and the wall time each install took."""
    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.learning.self_model import from_archive
    from sela_ros.core.storage import default_archive_path, load_archive
    from sela_ros.experiments.workers import own_and_near
    from sim_bridge.robots import get_robot

    archive = load_archive(default_archive_path())
    shipped = resolve_priors('auto', default_archive_path(), archive.params)
    truth = shipped.names.index(pair)
    priors = shipped
    for name in own_and_near(shipped, pair):
        priors = priors.without(name)
    legs = get_robot('hexapod').legs
    model = from_archive(archive, legs)
    lost = [legs.index(part.split(':')[1]) for part in pair.split(',')]
    known = ~shipped.inferred(truth)
    rng = np.random.default_rng(seed)
    wanted = None
    for g in rng.permutation(np.flatnonzero(known))[:20]:
        feet = archive.descriptors[g, 2:].copy()
        feet[lost] = 0.0
        model.observe(g, feet)
        wanted = wanted or model.request(priors)
    damage, gaits, _ = wanted
    gaits = gaits[known[gaits]]  # those the pair's table simulated
    t0 = time.perf_counter()
    out = model.install(priors, damage, gaits, shipped.generic_reward[truth, gaits],
                        shipped.fallen[truth, gaits])
    first = time.perf_counter() - t0
    refine = model.request(out)
    if refine is None:
        return out, first, None
    more = refine[1][known[refine[1]]]
    t0 = time.perf_counter()
    out = model.install(out, damage, more, shipped.generic_reward[truth, more],
                        shipped.fallen[truth, more])
    return out, first, time.perf_counter() - t0


def shipped_names():
    """The damages of the priors shipped beside the 8-D map (empty: none ship)."""
    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.storage import default_archive_path, load_archive

    priors = resolve_priors('auto', default_archive_path(),
                            load_archive(default_archive_path()).params)
    return () if priors is None else priors.names


def interleaved(args):
    """The step on the shipped map, the tables mixed, timed alternately with the defaults
    and with ``--caution``, ``--mean-affine``, ``--mean-descriptor``, ``--reach``: the same load
    for both."""
    runs = {'defaults': [], 'given': []}
    changes = []
    for k in range(args.interleave):
        for name, given in (('defaults', {}), ('given', {
                'caution': args.caution, 'mean_affine': args.mean_affine,
                'mean_descriptor': args.mean_descriptor, 'hyper_sd': args.hyper_sd,
                'kernel_changes': changes, 'reach': args.reach})):
            t, _, _, prior, _, cautious, mapped = bench_shipped(mixed=True, seed=k, **given)
            runs[name].append(t)
            print(f'  round {k + 1}/{args.interleave}, {name}: median {1e3 * t:.2f} ms '
                  f'(prior in use: {prior}{", affine map in use" if mapped else ""})'
                  f'{_on(cautious)}', flush=True)
    for name, times in runs.items():
        print(f'{name}: median of the rounds\' medians {1e3 * np.median(times):.2f} ms, '
              f'min {1e3 * np.min(times):.2f} ms over {len(times)} rounds')
    if args.hyper_sd is not None:
        for changed in (True, False):
            times = [t for t, c in changes if c == changed]
            if times:
                print(f'given, the steps that {"changed" if changed else "kept"} the kernel: '
                      f'{len(times)}, median {1e3 * np.median(times):.2f} ms')


def hyper_cost(repeats=15, seed=0):
    """``gp.hyper.sd``'s two costs on the shipped 8-D map, for N steps learnt: the grid of
    kernels scored on the steps' residuals (every step), and the GP refactorised under a new
    kernel (a step that changes it)."""
    from sela_ros.core.learning import CandidateSetGP, hyper
    from sela_ros.core.storage import default_archive_path, load_archive

    archive = load_archive(default_archive_path())
    candidates, prior = archive.normalised_descriptors(), archive.generic_reward
    rng = np.random.default_rng(seed)
    for n in (10, 30, 60):
        idx = rng.choice(len(candidates), n, replace=False)
        ys = 0.5 * prior[idx]
        model = CandidateSetGP(candidates, prior, sigma=0.3)
        model.fit(idx, ys)
        fit, change = [], []
        for k in range(repeats):
            t0 = time.perf_counter()
            hyper.choose(model.sq_distances, ys - prior[idx], 0.001, 0.3, 1.0, 0.5)
            fit.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            model.set_hyper(0.5 if k % 2 == 0 else 0.3, 0.1)
            change.append(time.perf_counter() - t0)
        print(f'  {n} steps, {len(candidates)} gaits: the grid of '
              f'{len(hyper.grid(0.3, 1.0))} kernels scored: median {1e3 * np.median(fit):.2f} '
              f'ms; the GP refactorised: median {1e3 * np.median(change):.2f} ms', flush=True)


def interleave_progress(args):
    """The step on the shipped map with ``acquisition.progress`` none and the weight asked
    for, one after the other ``--rounds`` times, so that the machine's load weighs on both
    alike."""
    times = {'none': [], args.interleave_progress: []}
    for r in range(args.rounds):
        for progress in times:
            t, _, _, prior, _, cautious, _ = bench_shipped(caution=args.caution,
                                                        mean_affine=args.mean_affine,
                                                        progress=progress)
            times[progress].append(t)
            print(f'  round {r + 1}/{args.rounds}, acquisition.progress {progress}: median '
                  f'{1e3 * t:.2f} ms (prior in use: {prior}){_on(cautious)}', flush=True)
    for progress, ts in times.items():
        print(f'shipped 8-D map, acquisition.progress {progress}: median of the rounds\' '
              f'medians {1e3 * float(np.median(ts)):.2f} ms (target < 20 ms)')


def _on(cautious):
    return ', caution on' if cautious else ''


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--toy-replicates', type=int, default=10)
    parser.add_argument('--max-candidates', type=float, default=1e6)
    parser.add_argument('--library', default=None,
                        help='also time a step with these damage priors (a library file)')
    parser.add_argument('--tables', type=int, default=84,
                        help='also time a step with this many tables made from the shipped '
                             'ones (a library of that size; 0: not)')
    parser.add_argument('--caution', type=float, default=None,
                        help='acquisition.caution for the steps on the shipped map (default: '
                             "the config's)")
    parser.add_argument('--mean-affine', default=None,
                        help="gp.mean.affine for the steps on the shipped map, a number or "
                             "none (default: the config's)")
    parser.add_argument('--progress', default=None,
                        help="acquisition.progress for the steps on the shipped map, a number "
                             "or none (default: the config's)")
    parser.add_argument('--interleave-progress', type=float, default=None,
                        help='only time the step on the shipped map with acquisition.progress '
                             'none and this weight, alternately (--rounds times each)')
    parser.add_argument('--rounds', type=int, default=5)
    parser.add_argument('--mean-descriptor', default=None,
                        help="gp.mean.descriptor for the steps on the shipped map, a number or "
                             "none (default: the config's)")
    parser.add_argument('--hyper-sd', default=None,
                        help="gp.hyper.sd for the steps on the shipped map (--interleave), a "
                             "number or none (default: the config's)")
    parser.add_argument('--reach', default=None,
                        help="acquisition.reach for the steps on the shipped map with "
                             "--interleave, a number or none (default: the config's)")
    parser.add_argument('--interleave', type=int, default=0,
                        help='only time the step on the shipped map (tables mixed) this many '
                             'times with the defaults and with the settings given, '
                             'alternately, and print both medians')
    parser.add_argument('--hyper-cost', action='store_true',
                        help="only time gp.hyper.sd's grid fit and refactorisation")
    args = parser.parse_args()
    if args.hyper_cost:
        hyper_cost()
        return
    if args.interleave_progress is not None:
        interleave_progress(args)
    elif args.interleave:
        interleaved(args)
        return
    print('SELA step (ask + tell + fall model, 8-D descriptors, 2 GR dims):')
    for m in (1e3, 1e4, 2e4, 1e5, 1e6):
        if m > args.max_candidates:
            break
        reps = 15 if m <= 1e5 else 5
        t, t_min, n = bench_step(int(m), repeats=reps)
        print(f'  {int(m):>8d} candidates, {n - reps + 1:2d}-{n:2d} observations: median '
              f'{1e3 * t:8.2f} ms, min {1e3 * t_min:8.2f} ms')
    t, t_min, gaits, prior, horizon, cautious, _ = bench_shipped(caution=args.caution,
                                                                  mean_affine=args.mean_affine)
    print(f'  shipped 8-D map ({gaits} gaits, SE(2), fall GP + support model, damage prior '
          f'in use: {prior}, {horizon} steps ahead), 20-34 observations: median '
          f'{1e3 * t:.2f} ms, min {1e3 * t_min:.2f} ms (target < 20 ms){_on(cautious)}')
    t, t_min, gaits, prior, horizon, cautious, _ = bench_shipped(mixed=True, caution=args.caution,
                                                                  mean_affine=args.mean_affine)
    print(f'  the same, the tables mixed on a damage two of them add up to (prior in use: '
          f'{prior}): median '
          f'{1e3 * t:.2f} ms, min {1e3 * t_min:.2f} ms (target < 20 ms){_on(cautious)}')
    pair = 'remove:front_left,remove:middle_left'
    if pair in shipped_names():
        t, t_min, gaits, prior, horizon, cautious, _ = bench_shipped(
            damage=pair, caution=args.caution, mean_affine=args.mean_affine)
        print(f'  the same on {pair} (the priors\' second tier; prior in use: {prior}): '
              f'median {1e3 * t:.2f} ms, min {1e3 * t_min:.2f} ms (target < 20 ms)'
              f'{_on(cautious)}')
    if pair in shipped_names():
        priors, install, refined = self_model_priors(pair)
        t, t_min, gaits, prior, horizon, cautious, _ = bench_shipped(
            damage=pair, priors=priors, caution=args.caution, mean_affine=args.mean_affine)
        print(f'  the same, its table left out and the self-model\'s table of it in the first '
              f'tier (prior in use: {prior}): median {1e3 * t:.2f} ms, min {1e3 * t_min:.2f} '
              f'ms (target < 20 ms){_on(cautious)}; the table installed in '
              f'{1e3 * install:.0f} ms, once, and refined in '
              f'{"-" if refined is None else f"{1e3 * refined:.0f}"} ms, once')
    for label, priors in ((f'{args.tables} tables like a library\'s', args.tables),
                          (args.library, args.library)):
        if not priors:
            continue
        for mixed in (False, True):
            t, t_min, gaits, prior, horizon, cautious, _ = bench_shipped(
                mixed=mixed, priors=priors, caution=args.caution, mean_affine=args.mean_affine)
            print(f'  the same with {label}, {"mixed" if mixed else "one table"} (prior in '
                  f'use: {prior}): median {1e3 * t:.2f} ms, min {1e3 * t_min:.2f} ms '
                  f'(target < 20 ms){_on(cautious)}')
    if args.toy_replicates < 1:
        return  # no toy experiment asked for
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, '-m', 'sela_ros.experiments.cli', 'toy',
                        '--replicates', str(args.toy_replicates), '--seed', '0', '--out', out,
                        '--workers', '2', '--quiet'], check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
    print(f'toy experiment, {args.toy_replicates} replicates x 4 methods, 2 workers, noise '
          f'std 0.1: {wall:.1f} s wall')


if __name__ == '__main__':
    main()
