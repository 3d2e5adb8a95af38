"""
The offline replay: recorded bags through the navigator's pipeline, into new bags.

``cli`` (the ``replay`` command), ``bag_input`` (the input bag, in stamp order), ``bag_output``
(the output bag, staged and placed), ``loop`` (the pipeline over a bag), ``run`` (one bag),
``many`` (many bags, ``--jobs``), ``scoring`` (against the simulator's truth), ``errors`` (one
line each). The names below are the replay's Python API.
"""

from vessel_kinematics.tools.replay.bag_input import (BagInput, DEFAULT_TOPICS, input_messages,
                                                      INPUT_TYPES, InputMessage, parse_remaps,
                                                      StampOrder, VELOCITY_TYPES)
from vessel_kinematics.tools.replay.bag_output import check_paths, is_bag_directory
from vessel_kinematics.tools.replay.cli import load_params, main, parse_param
from vessel_kinematics.tools.replay.errors import error_line, ReplayError
from vessel_kinematics.tools.replay.loop import OUTPUT_TYPES, replay_in_memory, Summary
from vessel_kinematics.tools.replay.many import (BagRow, find_bags, is_bag, is_many, output_name,
                                                 rows_table, run_many)
from vessel_kinematics.tools.replay.run import run
from vessel_kinematics.tools.replay.scoring import accuracy_report, dead_reckoning_run

__all__ = ['accuracy_report', 'BagInput', 'BagRow', 'check_paths', 'dead_reckoning_run',
           'DEFAULT_TOPICS', 'error_line', 'find_bags', 'input_messages', 'INPUT_TYPES',
           'InputMessage', 'is_bag', 'is_bag_directory', 'is_many', 'load_params', 'main',
           'output_name', 'OUTPUT_TYPES', 'parse_param', 'parse_remaps', 'replay_in_memory',
           'ReplayError', 'rows_table', 'run', 'run_many', 'StampOrder', 'Summary',
           'VELOCITY_TYPES']
