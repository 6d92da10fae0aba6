"""The floor of a pythonfmu doStep, shared by bench_fmu.py and bench_stepwise.py: an FMU
with one output and nothing computed."""

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


def build_empty_fmu(folder: str | Path) -> Path:
    """Build ``EmptyBench.fmu`` (FMI 2, pythonfmu) in ``folder`` and return its path."""
    from pythonfmu.builder import FmuBuilder

    script = Path(folder) / "empty_bench.py"
    script.write_text(EMPTY_SLAVE)
    return Path(FmuBuilder.build_FMU(script, dest=folder))
