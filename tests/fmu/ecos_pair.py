"""Run navsim's plant + estimator FMUs under ECOS (ecospy) and print the estimator's
outputs as JSON; run as a subprocess by test_ecos.py, so that a crash of the host (at
free or at exit) shows as an exit code instead of taking pytest down.

``python ecos_pair.py structure PLANT.fmu ESTIMATOR.fmu ORDER STEPS SEED``
    connect every estimator input to the plant output of the same name in an
    EcosSimulationStructure (ORDER: plant-first or estimator-first = the order in which
    the models are added);
``python ecos_pair.py ssp FILE.ssp - - STEPS SEED``
    load the system (connections and parameters) from an SSP archive.
"""

from __future__ import annotations

import json
import sys

NAV = ["nav.lat_rad", "nav.lon_rad", "nav.h_m", "nav.velocity_n[1]", "nav.velocity_n[2]", "nav.velocity_n[3]",
       "nav.heading_rad", "nav.pitch_rad", "nav.roll_rad", "nav.t_s"]


def main(mode: str, a: str, b: str, order: str, steps: int, seed: int) -> None:
    from ecospy import EcosSimulation, EcosSimulationStructure

    if mode == "structure":
        from fmpy import read_model_description

        ss = EcosSimulationStructure()
        models = [("plant", a), ("estimator", b)]
        for name, path in (models if order == "plant-first" else models[::-1]):
            ss.add_model(name, path)
        connect = {"Real": ss.make_real_connection, "Integer": ss.make_int_connection,
                   "Boolean": ss.make_bool_connection, "String": ss.make_string_connection}
        n = 0
        for v in read_model_description(b).modelVariables:
            if v.causality == "input":
                connect[v.type](f"plant::{v.name}", f"estimator::{v.name}")
                n += 1
        ss.add_parameter_set("navsim", {"plant::seed": seed})
        sim = EcosSimulation(structure=ss, step_size=0.01)
        parameter_set = "navsim"
    else:
        n = -1
        sim = EcosSimulation(ssp_path=a, step_size=0.01)
        parameter_set = "navsim"  # the SSD's parameter set (navsim.fmu.ssp.PARAMETER_SET)
    rows, counters = [], []
    sim.init(parameter_set=parameter_set)
    for _ in range(steps):
        sim.step()
        rows.append([sim.get_real(f"estimator::{k}") for k in NAV])
        counters.append([sim.get_integer("estimator::nav.step"), sim.get_integer("estimator::nav.lag_steps")])
    sim.terminate()
    sim.free()
    print(json.dumps({"connections": n, "rows": rows, "counters": counters}))


if __name__ == "__main__":
    m, a, b, order, steps, seed = sys.argv[1:7]
    main(m, a, b, order, int(steps), int(seed))
