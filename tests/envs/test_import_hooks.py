"""Registration on import and the lazy navsim.evaluate, checked in fresh interpreters."""

import subprocess
import sys


def run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout


def test_core_import_does_not_import_gymnasium():
    assert run("import sys, navsim, navsim.simulator, navsim.episode; print('gymnasium' in sys.modules)").strip() == "False"


def test_ids_registered_when_gymnasium_came_first():
    out = run("import gymnasium as gym, navsim; print('navsim/PaperRail-v0' in gym.registry)")
    assert out.strip() == "True"


def test_evaluate_is_reexported_lazily():
    out = run("import navsim; print(navsim.evaluate.__module__)")
    assert out.strip() == "navsim.envs.agent"


def test_ids_registered_when_navsim_came_first():
    # Gymnasium 1.x has no plugin discovery: navsim's one-shot import hook registers the ids
    out = run("import sys, navsim; print('gymnasium' in sys.modules); import gymnasium as gym; "
              "print('navsim/PaperRail-v0' in gym.registry, 'navsim/TrainDriving-v0' in gym.registry)")
    assert out.split() == ["False", "True", "True"]


def test_gym_make_after_navsim_in_either_order():
    outs = [run(f"{order}; env = gym.make('navsim/PaperRail-v0', timing={{'duration_s': 2.0}}); "
                "obs, info = env.reset(seed=0); print(type(env.unwrapped).__name__, obs['t'][0], info['seed'])")
            for order in ("import navsim; import gymnasium as gym", "import gymnasium as gym; import navsim")]
    assert outs[0] == outs[1]
    name, t0, seed = outs[0].split()
    assert name == "NavigationEnv" and float(t0) == 0.01 and seed == "0"  # first navigation step of the 100 Hz paper scenario


def test_import_navsim_envs_registers_without_hook_warnings():
    out = run("import warnings; warnings.simplefilter('error'); import navsim.envs, gymnasium as gym; "
              "print(sorted(k for k in gym.registry if k.startswith('navsim/')))")
    assert "navsim/AdaptiveFilter-v0" in out and "navsim/UrbanRoad-v0" in out


def test_module_prefixed_id_without_importing_navsim():
    out = run("import gymnasium as gym; env = gym.make('navsim.envs:navsim/UrbanRoad-v0'); print(env.spec.id)")
    assert out.strip() == "navsim/UrbanRoad-v0"


def test_missing_gymnasium_names_the_extra():
    # a finder that hides gymnasium, as on an install without the gym extra
    code = ("import sys, importlib.abc\n"
            "class Hide(importlib.abc.MetaPathFinder):\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name == 'gymnasium' or name.startswith('gymnasium.'): raise ModuleNotFoundError(name)\n"
            "sys.meta_path.insert(0, Hide())\n"
            "import navsim\n"
            "try:\n    import navsim.envs\nexcept ImportError as exc:\n    print(type(exc).__name__, exc)\n")
    out = run(code)
    assert "DependencyNotInstalled" in out and "navsim-track[gym]" in out


def test_version_command(capsys):
    import navsim
    from navsim.cli import main

    assert main(["--version"]) == 0  # main() returns argparse's exit status (one-line errors, issue 16)
    assert capsys.readouterr().out.strip() == f"navsim {navsim.__version__}"
    assert navsim.__version__ != "0.0.0+unknown"  # read from the installed distribution's metadata
