"""The papers' simulation studies through the built FMUs: ``python -m suspension_estimation.harness paper [--study NAME]``.

One module per study, over one shared runner (``harness.studies.runner``: runs, process pool,
common table and plot helpers); ``harness.studies.suite.PaperStudy`` runs the chosen studies and
writes one report. A study is a ``runner.Study`` object in its module; ``STUDIES`` below names
each, in the order of the report, with the line ``paper --help`` shows for it. A new
study is its module plus one entry here.

Nothing here imports a study module before it is asked for (``load``), so that importing the
runner (as ``harness.sweep`` and every worker process do) loads no study.
"""
from __future__ import annotations

from importlib import import_module

STUDIES = {  # --study NAME: ("module:object" under harness.studies, what it runs: its line of --help)
    "table2": ("paper000:TABLE2",
               "MME&KF paper Table 2: KF, MME&KF, KF at true mass, joint; 410/590/230 kg, 40 km/h"),
    "10ms": ("paper000:STUDY_10MS",
             "table2 at a 10 ms step, accelerations sampled at the step's end and averaged over it"),
    "mass": ("paper001:MASS",
             "vehicle-mass paper: its vehicle, sprung mass 260 -> 450 -> 350 kg in 8 s, ISO C"),
    "class": ("road_class:CLASS",
              "online ISO 8608 class of the default estimator: ISO A-E at 10, 20 and 30 m/s"),
    "robust": ("robust:ROBUST",
               "plant off the estimators' model: c_s, k_s, k_t, m_u, all four; air spring; 40, 80 km/h"),
    "vb": ("vb:VB_STUDY", "paper 004: VB-AKF ARMSE by Monte Carlo (no FMU); a loosening sensor mount (FMU)"),
    "paper003": ("paper003:PAPER003",
                 "paper 003: EKF, UKF, dual state + mass observer, air-spring plant, ISO A-C, 10 m/s"),
    "paper002": ("paper002:PAPER002",
                 "paper 002: its closed loop on the Fig. 6 scenario, passive, LQR on true states and on each "
                 "observer, 10 ms (alone: 1 seed, 200 s)"),
    "imm": ("imm:IMM",
            "paper 002: IMM mass, its Fig. 6 scenario (4 x 50 s), off its mass grid, damping 20 % off"),
    "sensors": ("sensors:SENSORS",
                "sensor offset, biases, gains, 2 ms delays, 200/100 Hz logging; linear and air-spring plant "
                "(alone: ISO C, 40 km/h, 2 seeds, 30 s)"),
}


def load(name: str):
    """The ``runner.Study`` registered as ``name``; ``ValueError`` naming the known ones if none."""
    if name not in STUDIES:
        raise ValueError(f"--study: no study {name!r} (studies: {', '.join(STUDIES)})")
    module, obj = STUDIES[name][0].split(":")
    return getattr(import_module(f"{__name__}.{module}"), obj)
