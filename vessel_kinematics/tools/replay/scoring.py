"""
Scoring a replay against the simulator's truth, beside a dead-reckoning-only replay.

:func:`accuracy_report` scores a bag of outputs (:mod:`vessel_kinematics.tools.evaluate`: RMS
and max errors of position, heading, course, sideslip, current) and replays the same inputs in
memory with ``gnss.enabled: false`` (:func:`dead_reckoning_run`), whose fixes then only set the
origin: the paragraph says what the fusion bought.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Mapping, Sequence

from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.tools import bags, evaluate
from vessel_kinematics.tools.replay.bag_input import parse_remaps
from vessel_kinematics.tools.replay.loop import replay_in_memory

__all__ = ['accuracy_report', 'dead_reckoning_run']


def dead_reckoning_run(inputs_bag: str | Path, params: NavigatorParams | None = None,
                       remaps: Sequence[str] | Mapping[str, str] | None = None,
                       ) -> evaluate.Run:
    """
    Replay a bag's inputs in memory with ``gnss.enabled: false``: the dead-reckoning-only run.

    The fixes then only set the origin (the first fix, as in the fused run, unless ``origin`` is
    a parameter); the truth and reference topics are taken from the same bag.
    """
    params = params if params is not None else NavigatorParams()
    topics_map = parse_remaps(remaps)
    outputs, _ = replay_in_memory(inputs_bag, dataclasses.replace(params, gnss_enabled=False),
                                  remaps)
    extra = bags.read_topics([inputs_bag], set(evaluate.TRUTH_TOPICS)
                             | {evaluate.COG_SOG_TOPIC, topics_map['fix']})
    return evaluate.run_from_messages({**outputs, **extra}, fix_topic=topics_map['fix'],
                                      label='dead reckoning')


def accuracy_report(bag: str | Path, params: NavigatorParams | None = None,
                    remaps: Sequence[str] | Mapping[str, str] | None = None,
                    inputs_bag: str | Path | None = None,
                    dead_reckoning: bool = True,
                    ) -> tuple[str, evaluate.Run, evaluate.Run | None]:
    """
    Score the outputs in ``bag`` against its truth, with a dead-reckoning-only replay beside.

    ``inputs_bag`` holds the navigator's inputs and truth when ``bag`` does not (default:
    ``bag`` itself, as the replay copies its inputs). Return (text, fused run, DR run or None);
    the text says so when there is no truth.
    """
    fix_topic = parse_remaps(remaps)['fix']
    run = evaluate.load_run(bag, fix_topic=fix_topic, fixes_bag=inputs_bag)
    scores = evaluate.accuracy(run)
    if scores is None:
        return 'no truth topics in the bag: accuracy not scored', run, None
    dr_run = None
    dr_scores = None
    if dead_reckoning:
        dr_run = dead_reckoning_run(inputs_bag if inputs_bag is not None else bag, params,
                                    remaps)
        dr_scores = evaluate.accuracy(dr_run)
    return evaluate.format_accuracy(scores, dr_scores), run, dr_run
