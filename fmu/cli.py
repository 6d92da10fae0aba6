"""The ``navsim fmu`` sub-commands (registered by :func:`add_fmu_parser`).

``navsim fmu build SCENARIO --what plant|estimator --fmi 2|3 -o FILE.fmu``
    build an FMU (``--estimator NAME`` for the estimator FMU; ``--set KEY=VALUE``
    overrides the scenario before embedding it).
``navsim fmu ssp SCENARIO -o PAIR.ssp --estimator NAME --seed N``
    write an SSP archive: the plant and estimator FMUs (FMI 2) and SystemStructure.ssd
    with every connection and the parameters (:mod:`navsim.fmu.ssp`).
``navsim fmu validate FILE.fmu ...``
    fmpy's validation; exit status 1 when a problem is found.
``navsim fmu cosim PLANT.fmu ESTIMATOR.fmu --seed N [--master plant-first|estimator-first|jacobi]``
    run the two FMUs connected (Python master over fmpy) and print the episode score.
``navsim fmu run SCENARIO --motion-fmu TRAIN.fmu --motion-map s=s,speed=v,accel=a
--motion-input F_traction=2e5 --estimator NAME --seed N``
    run an episode whose motion comes from an external FMU and print the score.
``navsim fmu host-env``
    print the LD_PRELOAD / PYTHONHOME / PYTHONPATH lines a non-Python host needs.
``navsim fmu info``
    print what a host needs to run navsim's FMUs.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING, Any

from navsim.errors import NavsimError

if TYPE_CHECKING:
    from navsim.episode import EpisodeRecord
    from navsim.scenario import Scenario

__all__ = ["add_fmu_parser"]


def _scenario(args: argparse.Namespace) -> Scenario:
    from navsim.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    if getattr(args, "set", None):
        from navsim.overrides import parse_overrides

        scenario = scenario.with_overrides(parse_overrides(args.set))
    return scenario


def _print_score(record: EpisodeRecord) -> None:
    from navsim.metrics import score_episode

    print(json.dumps(score_episode(record).to_flat_dict(), indent=1))


def _cmd_build(args: argparse.Namespace) -> int:
    from .build import build_fmu

    path = build_fmu(_scenario(args), args.what, int(args.fmi), args.output, estimator=args.estimator,
                     estimator_options=args.estimator_options or "")
    print(path)
    if not args.no_validate:
        try:
            from fmpy.validation import validate_fmu
        except ImportError:
            return 0
        problems = validate_fmu(str(path))
        for p in problems:
            print(f"validation: {p}", file=sys.stderr)
        return 1 if problems else 0
    return 0


def _cmd_ssp(args: argparse.Namespace) -> int:
    from .ssp import build_ssp

    path = build_ssp(_scenario(args), args.output, estimator=args.estimator,
                     estimator_options=args.estimator_options or "", seed=args.seed)
    print(path)
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    try:
        from fmpy.validation import validate_fmu
    except ImportError:
        from navsim.errors import DependencyNotInstalled

        raise DependencyNotInstalled("fmpy", "fmu") from None
    bad = 0
    for path in args.fmu:
        problems = validate_fmu(path)
        print(f"{path}: {'ok' if not problems else f'{len(problems)} problem(s)'}")
        for p in problems:
            print(f"  {p}")
        bad += bool(problems)
    return 1 if bad else 0


def _cmd_cosim(args: argparse.Namespace) -> int:
    from .master import cosimulate

    record = cosimulate(args.plant, args.estimator_fmu, seed=args.seed, steps=args.steps, name="fmu",
                        master=args.master)
    _print_score(record)
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from navsim import estimators
    from navsim.episode import run_episode

    from .motion import FmuDrivenSimulator, FmuMotionSource, parse_mapping

    scenario = _scenario(args)
    mapping = parse_mapping(args.motion_map, args.motion_input)
    source = FmuMotionSource(args.motion_fmu, mapping, scenario.timing.nav_period_s)
    try:
        sim = FmuDrivenSimulator(scenario, source)
        record = run_episode(sim.scenario, estimators.make(args.estimator), seed=args.seed, simulator=sim,
                             name=args.estimator)
    finally:
        source.close()
    _print_score(record)
    return 0


def _cmd_host_env(args: argparse.Namespace) -> int:
    import shlex

    from .build import host_environment

    for key, value in host_environment().items():
        print(f"export {key}={shlex.quote(value)}")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from .build import HOST_REQUIREMENTS

    print(HOST_REQUIREMENTS, end="")
    return 0


def add_fmu_parser(subparsers: argparse._SubParsersAction[Any]) -> None:
    """Register ``navsim fmu ...`` on the ``navsim`` command's sub-parsers."""
    fmu = subparsers.add_parser("fmu", help="build, validate and run navsim FMUs; external FMUs as motion sources")
    sub = fmu.add_subparsers(dest="fmu_command", required=True)

    p = sub.add_parser("build", help="build a plant or estimator FMU of a scenario")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("--what", choices=("plant", "estimator"), default="plant")
    p.add_argument("--fmi", choices=("2", "3"), default="2", help="FMI version (2: pythonfmu, 3: pythonfmu3)")
    p.add_argument("-o", "--output", required=True, help="the .fmu file to write")
    p.add_argument("--estimator", default=None, help="estimator of the estimator FMU (default paper-ekf or lc-ekf)")
    p.add_argument("--estimator-options", default="", help="TOML key = value options for the estimator")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a scenario field")
    p.add_argument("--no-validate", action="store_true", help="skip fmpy validation of the result")
    p.set_defaults(func=_cmd_build)

    p = sub.add_parser("ssp", help="write an SSP archive: plant + estimator FMUs and SystemStructure.ssd")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("-o", "--output", required=True, help="the .ssp file to write")
    p.add_argument("--estimator", default=None, help="estimator of the estimator FMU (default paper-ekf or lc-ekf)")
    p.add_argument("--estimator-options", default="", help="TOML key = value options for the estimator")
    p.add_argument("--seed", type=int, default=0, help="the plant's seed parameter in the SSD")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a scenario field")
    p.set_defaults(func=_cmd_ssp)

    p = sub.add_parser("validate", help="validate FMUs with fmpy")
    p.add_argument("fmu", nargs="+")
    p.set_defaults(func=_cmd_validate)

    p = sub.add_parser("cosim", help="run a plant FMU and an estimator FMU connected; print the score")
    p.add_argument("plant")
    p.add_argument("estimator_fmu")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, default=None, help="stop after this many navigation steps")
    p.add_argument("--master", choices=("plant-first", "estimator-first", "jacobi"), default="plant-first",
                   help="order of each step: Gauss-Seidel plant first (default), estimator first, or Jacobi "
                        "(the last two: the estimate refers to the previous step)")
    p.set_defaults(func=_cmd_cosim)

    p = sub.add_parser("run", help="run an episode driven by an external motion FMU; print the score")
    p.add_argument("scenario")
    p.add_argument("--motion-fmu", required=True, help="co-simulation FMU giving position/speed/acceleration")
    p.add_argument("--motion-map", default="s=s,speed=v,accel=a",
                   help="FMU variables for arc length, speed, acceleration; offset=M, scale=+1|-1")
    p.add_argument("--motion-input", action="append", default=[], metavar="NAME=VALUE",
                   help="constant FMU input or parameter (e.g. F_traction=2e5)")
    p.add_argument("--estimator", default="ins-only")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a scenario field")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("host-env", help="the environment a non-Python host needs (export lines)")
    p.set_defaults(func=_cmd_host_env)

    p = sub.add_parser("info", help="what a host needs to run navsim's FMUs")
    p.set_defaults(func=_cmd_info)


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry point (``python -m navsim.fmu.cli``) until ``navsim`` wires it in."""
    parser = argparse.ArgumentParser(prog="navsim")
    add_fmu_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except NavsimError as exc:
        print(f"navsim: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
