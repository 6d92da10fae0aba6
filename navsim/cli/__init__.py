"""The ``navsim`` command.

Sub-commands
------------
``navsim --version``                         print the installed version
``navsim scenarios``                         list the bundled scenarios
``navsim estimators [NAME ...] [--json]``    list the estimators, their options and availability
``navsim show SCENARIO``                     print the resolved scenario as TOML
``navsim simulate SCENARIO --seed N -o F``   write truth and measurements (NPZ or CSV)
``navsim run SCENARIO --estimator NAME``     score one estimator on one episode
``navsim bench SCENARIO --estimators A,B``   compare estimators across seeds
``navsim campaign SPEC.toml [--scheduler]``  scenarios x estimators x seeds, local or on Dask
``navsim paper 000|001|003 [--json]``        rerun a seed paper's experiments
``navsim fmu build|validate|cosim|run|info``  FMUs: export navsim, import motion FMUs

Exit status: 0 on success, 2 on bad input (the message names the field), 1 otherwise.
"""
from .entry import expected_failure, main
from .parser import build_parser

__all__ = ["main", "build_parser", "expected_failure"]
