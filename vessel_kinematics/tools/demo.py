"""
The README's first command: the navigator, for real, on a simulated voyage with ground truth.

``python -m vessel_kinematics.tools.demo --output demo_out`` (what ``make demo`` runs, after
``source install/setup.bash``):

1. simulates a voyage with :mod:`vessel_kinematics.tools.sim` (inputs and truth in a bag);
2. starts the installed ``navigator`` exactly as ``ros2 run vessel_kinematics navigator`` would,
   found through the ament index, with ``--params-file <share>/config/demo.yaml -p
   use_sim_time:=true``;
3. publishes the voyage's ``/fix``, ``/imu`` and ``/velocity`` over DDS (reliable QoS) with a
   ``/clock`` running ``--rate`` times faster than real time, each at its log time: when it
   reached the vessel's ROS graph, a fix 0.1 to 0.5 s after its stamp (``--fix-latency``), the
   IMU and the log 1 to 5 ms after theirs, so the navigator fuses late fixes at their stamps as
   on board (its ``history_length``); and records every output of the node (those of the
   interface table, :mod:`vessel_kinematics.ros.interface`, and ``/diagnostics``; ``/tf`` and
   ``/tf_static`` where tf2_msgs exists) as it arrives;
4. stops the node with SIGINT, writes one mcap bag with the inputs, the truth and the outputs;
5. scores the outputs against truth beside a dead-reckoning-only replay
   (:mod:`vessel_kinematics.tools.evaluate`), draws the figure
   (:mod:`vessel_kinematics.tools.plot`), and prints the paths of the bag, the PNG and the
   summary.

The DDS domain is the environment's ``ROS_DOMAIN_ID`` (the Makefile picks one per run). The exit
status is 0 on success and 1 with a one-line reason on failure (e.g. the navigator is not
installed: run ``make build`` first).
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import shutil
import signal
import sys
import time
from typing import Any, Sequence

from vessel_kinematics.ros import interface
from vessel_kinematics.tools.demo_live import (Bridge, DemoError, diagnostics_values,
                                               INPUT_TOPICS, Installation, lead_limit, Message,
                                               NavigatorProcess, play, read_bag, say,
                                               start_clock, tf_available, TF_TOPICS)
from vessel_kinematics.tools.sim_model import FIX_LATENCY

__all__ = ['ESTIMATES', 'find_installation', 'main', 'OUTPUT_TOPICS', 'PACKAGE', 'run',
           'VOYAGE_ERRORS', 'write_run_bag']

PACKAGE = 'vessel_kinematics'
#: The demo voyage's sensor errors: a speed log (surge only, through the water) reading 10 %
#: low and a 3 deg leeway, which the navigator estimates with the current (sim.VoyageConfig).
VOYAGE_ERRORS: dict[str, Any] = {'log_scale': 0.9, 'log_surge_only': True,
                                 'leeway': math.radians(3.0)}
#: The /diagnostics values the demo's summary quotes.
ESTIMATES = ('log scale', 'leeway (deg)', 'turn drift (m/rad)', 'current set (deg)',
             'current drift (kn)')
#: Every other output of the navigator the demo records, with its type (as the replay writes).
OUTPUT_TOPICS: dict[str, str] = {
    topic: msg_type for topic, msg_type in interface.types(
        interface.Role.OUTPUT, interface.Role.AUXILIARY).items() if topic not in TF_TOPICS}
# --------------------------------------------------------------------------------------------
# Locating the installed navigator


def find_installation() -> Installation:
    """Return the installed navigator as ``ros2 run`` finds it, or raise DemoError."""
    hint = 'run `make build` first (or `source install/setup.bash` in this shell)'
    try:
        from ament_index_python.packages import (get_package_prefix,
                                                 get_package_share_directory,
                                                 PackageNotFoundError)
    except ImportError as error:
        raise DemoError(f'ament_index_python is not importable ({error}): {hint}') from error
    try:
        prefix = Path(get_package_prefix(PACKAGE))
        share = Path(get_package_share_directory(PACKAGE))
    except PackageNotFoundError as error:
        raise DemoError(f'the {PACKAGE} package is not installed in AMENT_PREFIX_PATH='
                        f'{os.environ.get("AMENT_PREFIX_PATH", "")!r}: {hint}') from error
    navigator = prefix / 'lib' / PACKAGE / 'navigator'
    if not os.access(navigator, os.X_OK):
        raise DemoError(f'{navigator} is missing or not executable: {hint}')
    return Installation(navigator=navigator, share=share)


# --------------------------------------------------------------------------------------------
# The voyage's messages


def write_run_bag(path: Path, messages: Sequence[Message], types: dict[str, str]) -> Path:
    """
    Write all messages (sorted by log time) to a new rosbag2 mcap bag.

    Each connection offers the interface table's QoS (latched ``/origin``, ``/truth/origin``
    and ``/tf_static``: transient-local, keep last 1), as the replay's output does.
    """
    from vessel_kinematics.tools import bags

    ordered = sorted(messages, key=lambda m: m.log_ns)
    present = {m.topic for m in ordered}
    return bags.write_bag(path, ((m.topic, m.log_ns, m.data) for m in ordered),
                          {t: ty for t, ty in types.items() if t in present})


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Run the whole demo; return the paths and numbers (raises DemoError on failure)."""
    from vessel_kinematics.ros.params import ParameterError
    from vessel_kinematics.tools import plot, replay, sim

    start_clock()
    t_start = time.monotonic()
    installation = find_installation()
    params_file = args.params_file or installation.share / 'config' / 'demo.yaml'
    try:
        params = replay.load_params(params_file)
    except ParameterError as error:
        raise DemoError(str(error)) from error
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    voyage_bag = out / 'voyage'
    run_bag = out / 'navigator_run'
    png = out / 'demo_voyage.png'
    summary_path = out / 'summary.txt'
    log_path = out / 'navigator.log'
    for stale in (voyage_bag, run_bag):
        if stale.exists():
            shutil.rmtree(stale)
    domain = os.environ.get('ROS_DOMAIN_ID', '0')
    say(f'navigator: {installation.navigator}')
    say(f'parameters: {params_file}; DDS domain {domain}')

    say(f'1/5 simulating a {args.duration:.0f} s voyage (seed {args.seed}) -> {voyage_bag}')
    config = sim.VoyageConfig(duration=args.duration, seed=args.seed,
                              reference=params.velocity_reference,
                              fix_latency=tuple(args.fix_latency),
                              stamp_on_receipt=args.stamp_on_receipt, **VOYAGE_ERRORS)
    try:
        sim.validate(config)
    except ValueError as error:
        raise DemoError(str(error)) from error
    # The player's lead and the inputs' latency must fit in the node's history.
    lead = lead_limit(params.history_length, 0.0 if config.stamp_on_receipt else max(
        config.fix_latency[1], config.imu_latency[1], config.velocity_latency[1]))
    voyage = sim.generate(voyage_bag, config)
    messages, types = read_bag(voyage_bag)
    inputs = [m for m in messages if m.topic in INPUT_TOPICS]
    counts = ', '.join(f'{t} {n}' for t, n in voyage['messages'].items())
    say(f'    {voyage["distance"]:.0f} m over ground; {counts}')
    say(f'    {_latency_text(config)}; navigator history_length '
        f'{params.history_length:g} s, player lead {lead:g} s')

    output_types = dict(OUTPUT_TOPICS)
    if tf_available():
        output_types.update(TF_TOPICS)
    say('2/5 starting the navigator (use_sim_time) and connecting over DDS')
    bridge = Bridge(output_types)
    navigator = NavigatorProcess(installation, params_file, log_path)
    return_code = None
    try:
        bridge.publish_clock(inputs[0].log_ns)
        deadline = time.monotonic() + args.connect_timeout
        while not bridge.connected():
            if not navigator.alive():
                raise DemoError('the navigator exited at start-up; its log:\n'
                                + navigator.log_tail())
            if time.monotonic() > deadline:
                raise DemoError(f'the navigator did not connect within {args.connect_timeout} '
                                f's (DDS domain {domain}); its log:\n' + navigator.log_tail())
            bridge.publish_clock(inputs[0].log_ns)
            time.sleep(0.1)
        # /clock again now that the node subscribes: before it, its clock reads 0 and every
        # stamp would be far in its future (refused as future_stamp).
        for _ in range(6):
            bridge.publish_clock(inputs[0].log_ns)
            time.sleep(0.05)
        say(f'3/5 publishing {len(inputs)} messages with /clock at {args.rate:g}x real time')
        period = 1.0 / params.publish_rate if params.publish_rate > 0 else 0.0
        stats = play(bridge, inputs, args.rate, navigator, period, lead)
        stats.navigator_cpu = navigator.cpu_seconds()
    finally:
        return_code = navigator.stop()
        bridge.close()
    if return_code != 0:
        say(f'    warning: the navigator exited with status {return_code} on SIGINT')
    recording = bridge.recording
    if not recording.counts.get('/odometry'):
        raise DemoError('no /odometry received from the navigator; its log:\n'
                        + navigator.log_tail())
    diag = diagnostics_values(recording.last_diagnostics)
    say(f'    played in {stats.wall:.1f} s wall; navigator stopped (exit {return_code}); '
        f'outputs: ' + ', '.join(f'{t} {n}' for t, n in sorted(recording.counts.items())))

    say(f'4/5 writing {run_bag}')
    write_run_bag(run_bag, messages + recording.messages, {**types, **output_types})

    say('5/5 scoring against truth (and a dead-reckoning-only replay) and plotting')
    text, fused_run, dr_run = replay.accuracy_report(run_bag, params)
    title = (f'vessel_kinematics navigator (live over DDS, {args.rate:g}x) on a simulated '
             f'{args.duration:.0f} s voyage')
    plot.plot(fused_run, png, dead_reckoning=dr_run, title=title)

    accepted = {name: diag.get(f'accepted {name}', '?') for name in ('fix', 'imu', 'velocity')}
    rejected = {k[len('rejected '):]: v for k, v in diag.items() if k.startswith('rejected ')}
    lines = [
        f'vessel_kinematics demo: {args.duration:.0f} s simulated voyage (seed {args.seed}, '
        f'speed log through the water reading {config.log_scale:g} x, leeway '
        f'{math.degrees(config.leeway):g} deg, GNSS outage '
        + ('{:.0f}-{:.0f} s'.format(*voyage['outage']) if voyage['outage'] else 'none') + ')',
        f'  navigator    {installation.navigator} (live, use_sim_time, /clock at '
        f'{args.rate:g}x: {stats.wall:.1f} s wall, node CPU {stats.navigator_cpu:.1f} s)',
        f'  delivery     {_latency_text(config)}; each published at its arrival',
        '  published    ' + ', '.join(f'{t} {n}' for t, n in stats.published.items()),
        '  accepted     ' + ', '.join(f'{k} {v}' for k, v in accepted.items())
        + ('; rejected ' + ', '.join(f'{k} {v}' for k, v in rejected.items())
           if rejected else ''),
        '  outputs      ' + ', '.join(f'{t} {n}' for t, n in sorted(recording.counts.items())),
        f'  final mode   {diag.get("mode", "?")}',
        '  estimated    ' + ', '.join(f'{k} {diag[k]}' for k in ESTIMATES if k in diag)
        + f' (truth: log scale {config.log_scale:g}, leeway {math.degrees(config.leeway):g} deg)',
        '',
        text,
        '',
        '  dead reckoning = the same inputs replayed with gnss.enabled: false (the first fix only '
        'sets the origin)' + (';\n  a log through the water cannot observe the current, '
                              'so it drifts with it' if config.reference == 'water' else ''),
    ]
    summary = '\n'.join(lines) + '\n'
    summary_path.write_text(summary)
    return {'bag': run_bag, 'png': png, 'summary': summary_path, 'text': summary,
            'voyage': voyage_bag, 'log': log_path, 'seconds': time.monotonic() - t_start}


def _latency_text(config: Any) -> str:
    """Return the voyage's delivery latencies and stamping as one line of text."""
    def ms(bounds: tuple[float, float]) -> str:
        return f'{1e3 * bounds[0]:g}-{1e3 * bounds[1]:g} ms'
    return (f'latency fix {ms(config.fix_latency)}, imu {ms(config.imu_latency)}, velocity '
            f'{ms(config.velocity_latency)} after '
            + ('the measurement, stamped on receipt' if config.stamp_on_receipt
               else 'the stamp'))


def _parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='python -m vessel_kinematics.tools.demo',
        description='Simulate a voyage, run the installed navigator on it over DDS at an '
                    'accelerated /clock, record its outputs, score them against truth and '
                    'plot them. Needs `source install/setup.bash` (make demo does it).')
    parser.add_argument('--output', type=Path, default=Path('demo_out'),
                        help='directory for the bags, the figure and the summary '
                             '(default %(default)s)')
    parser.add_argument('--duration', type=float, default=300.0,
                        help='voyage length in s of sim time (default %(default)s)')
    parser.add_argument('--seed', type=int, default=1, help='simulation seed (default 1)')
    parser.add_argument('--rate', type=float, default=10.0,
                        help='speed of the /clock relative to real time (default %(default)s)')
    parser.add_argument('--fix-latency', type=float, nargs=2, metavar=('MIN', 'MAX'),
                        default=list(FIX_LATENCY),
                        help='delivery latency of the GNSS fixes: each arrives a time drawn in '
                             'MIN..MAX s after its stamp (default %(default)s; 0 0: none)')
    parser.add_argument('--stamp-on-receipt', action='store_true',
                        help='the drivers stamp on receipt: each stamp is its arrival, late '
                             'by the latency (default: stamped at measurement)')
    parser.add_argument('--params-file', type=Path, default=None,
                        help='navigator parameters (default: the installed config/demo.yaml)')
    parser.add_argument('--connect-timeout', type=float, default=30.0,
                        help='seconds to wait for the navigator on DDS (default %(default)s)')
    args = parser.parse_args(argv)
    if not 0.1 <= args.rate <= 100.0:
        parser.error(f'--rate must be between 0.1 and 100, got {args.rate}')
    if not 1.0 <= args.duration <= 3600.0:
        parser.error(f'--duration must be between 1 and 3600 s, got {args.duration}')
    return args


def _terminate(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt(f'signal {signum}')


def main(argv: Sequence[str] | None = None) -> int:
    """Run the demo; print the paths of the bag, the figure and the summary; return 0 or 1."""
    args = _parse_args(argv)
    # SIGTERM (e.g. timeout) stops the navigator as Ctrl-C does: it runs in its own session.
    signal.signal(signal.SIGTERM, _terminate)
    try:
        result = run(args)
    except DemoError as error:
        print(f'[demo] error: {error}', file=sys.stderr, flush=True)
        return 1
    except KeyboardInterrupt:
        print('[demo] interrupted', file=sys.stderr, flush=True)
        return 130
    print()
    print(result['text'])
    say(f'done in {result["seconds"]:.0f} s')
    print(f'  bag:     {result["bag"]}')
    print(f'  plot:    {result["png"]}')
    print(f'  summary: {result["summary"]}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
