"""The named studies: each one file here with ``STUDY = Study(...)``, found by ``studies()`` (nothing else imports
them). A study is data: the grid command it runs through (its kind) and the options that define it: tasks,
methods or strategies, students, baselines, seeds, base seed, budget, engine, overrides, folders. Its cells and
its report are the kind's (``experiments.reproduce``: a task x method grid of one student and preset, Table 2's
artefacts; ``experiments.screen``: teacher variants; ``experiments.benchmark``: students x strategies with
verdicts against each student's baseline, the aggregate and the cost). ``python -m experiments.grid <study>``
runs, resumes or rebuilds any of them."""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
from typing import Any

KINDS = ("reproduce", "screen", "benchmark")


@dataclasses.dataclass(frozen=True)
class Study:
    """A named grid.

    Attributes:
      name: how ``python -m experiments.grid`` names it.
      kind: the grid command whose cells and report it has (``KINDS``).
      about: one line: what it measures and where its results are.
      settings: the kind's options that define it, as the kind's parser stores them (its ``dest`` names and
        values); the others keep the kind's defaults.
    """

    name: str
    kind: str
    about: str
    settings: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"study {self.name!r}: kind {self.kind!r} is not one of {', '.join(KINDS)}")


def studies() -> dict[str, Study]:
    """Every study of this package by name, in name order."""
    found = {}
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("_"):  # a part that several studies share, not a study
            continue
        study = importlib.import_module(f"{__name__}.{info.name}").STUDY
        if study.name in found:
            raise ValueError(f"two studies are named {study.name!r}")
        found[study.name] = study
    return dict(sorted(found.items()))
