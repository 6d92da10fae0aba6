"""The floor of a pythonfmu doStep, shared by bench_fmu.py and bench_stepwise.py: an FMU
with one output and nothing computed, for FMI 2 (pythonfmu) and FMI 3 (pythonfmu3)."""

from __future__ import annotations

import textwrap
from pathlib import Path

EMPTY_SLAVE = textwrap.dedent('''\
    from pythonfmu import Fmi2Causality, Fmi2Slave, Real


    class EmptyBench(Fmi2Slave):
        """One output, nothing computed: the floor of a pythonfmu doStep."""

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.y = 0.0
            self.register_variable(Real("y", causality=Fmi2Causality.output))

        def do_step(self, current_time, step_size):
            return True
    ''')


EMPTY_SLAVE3 = textwrap.dedent('''\
    from pythonfmu3 import Fmi3Causality, Fmi3Slave, Fmi3Variability, Float64
    from pythonfmu3.fmi3slave import Fmi3StepResult

    _OK = Fmi3StepResult()


    class EmptyBench3(Fmi3Slave):
        """The independent variable and one output, nothing computed: the floor of a pythonfmu3 doStep."""

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.time = 0.0
            self.y = 0.0
            self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                           variability=Fmi3Variability.continuous))
            self.register_variable(Float64("y", causality=Fmi3Causality.output))

        def do_step(self, current_time, step_size):
            return _OK
    ''')


def build_empty_fmu(folder: str | Path, fmi: int = 2) -> Path:
    """Build ``EmptyBench.fmu`` (FMI 2, pythonfmu) or ``EmptyBench3.fmu`` (FMI 3,
    pythonfmu3) in a folder of its own under ``folder`` and return its path."""
    if fmi == 2:
        from pythonfmu.builder import FmuBuilder
    elif fmi == 3:
        from pythonfmu3.builder import FmuBuilder
    else:
        raise ValueError(f"fmi must be 2 or 3, not {fmi!r}")
    out = Path(folder) / f"empty{fmi}"
    out.mkdir(exist_ok=True)
    script = out / ("empty_bench.py" if fmi == 2 else "empty_bench3.py")
    script.write_text(EMPTY_SLAVE if fmi == 2 else EMPTY_SLAVE3)
    return Path(FmuBuilder.build_FMU(script, dest=out))
