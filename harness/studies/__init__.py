"""The papers' simulation studies through the built FMUs: ``python -m suspension_estimation.harness paper [--study NAME]``.

One module per study, over one shared runner (``harness.studies.runner``: runs, process pool,
common table and plot helpers); ``harness.studies.suite.PaperStudy`` runs the chosen studies and
writes one report. A study is a ``runner.Study`` object in its module; ``STUDIES`` below names
each, in the order of the report. A new study is its module plus one line here.

Nothing here imports a study module before it is asked for (``load``), so that importing the
runner (as ``harness.sweep`` and every worker process do) loads no study.
"""
from __future__ import annotations

from importlib import import_module

STUDIES = {  # --study NAME: "module:object" under harness.studies
    "table2": "paper000:TABLE2",  # MME&KF paper, Table 2
    "10ms": "paper000:STUDY_10MS",  # Table 2 at a 10 ms step, point-sampled vs averaged accelerations
    "mass": "paper001:MASS",  # vehicle-mass paper, the 260 -> 450 -> 350 kg case
    "class": "road_class:CLASS",  # online ISO 8608 class, A..E at 10-30 m/s
    "robust": "robust:ROBUST",  # the plant off the estimators' model (vehicle offsets, nonlinear plant)
    "vb": "vb:VB_STUDY",  # paper 004: VB-AKF ARMSE table, the smoother's share, a loosening sensor mount
    "paper003": "paper003:PAPER003",  # paper 003: EKF, UKF, dual observer on the nonlinear plant
    "imm": "imm:IMM",  # IMM paper, Fig. 6 scenario, on and off the bank's grid, damping off
}


def load(name: str):
    """The ``runner.Study`` registered as ``name``; ``ValueError`` naming the known ones if none."""
    if name not in STUDIES:
        raise ValueError(f"--study: no study {name!r} (studies: {', '.join(STUDIES)})")
    module, obj = STUDIES[name].split(":")
    return getattr(import_module(f"{__name__}.{module}"), obj)
