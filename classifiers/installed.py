"""Where the context models are installed, and which one the service and ``pdr classify`` use for each phone
placement. Light on purpose: naming a model needs neither scikit-learn nor XGBoost (:mod:`classifiers.artifacts`
loads and saves them).
"""

from __future__ import annotations

import os
from pathlib import Path
from types import MappingProxyType

from pdr.errors import InputError

#: Folder of the shipped models (override with ``PDR_MODELS_DIR``).
MODELS_DIR = Path(os.environ.get("PDR_MODELS_DIR", Path(__file__).resolve().parents[1] / "models"))
#: The model ``pdr classify`` uses when none is named.
DEFAULT_MODEL = "motion_mode"
#: Motion-mode model of each pipeline placement group (``pdr.phone.configure.placement_group``); the service
#: applies the one installed under ``models/`` and otherwise builds the modes from the pipeline's step patterns.
#: Only the pocket model is shipped. A hand-held model trained as ``pdr train motion_mode --data
#: ../shared/data/ipin2023_t3 ../shared/data/ms_indoor_location --out models/motion_mode_hand --cv`` separates
#: standing from walking (leave-one-recording-out F1 0.96/0.97) but not stairs or elevator rides (F1 <= 0.4:
#: three multi-floor recordings, and the MS logs have no barometer, so the group is dropped), where the step
#: patterns do better (``pdr eval classifier motion_mode --targets``, docs/modes.md); install one only when its card
#: shows it.
PLACEMENT_MODELS = MappingProxyType({"pocket": DEFAULT_MODEL, "hand": "motion_mode_hand",
                                     "torso": "motion_mode_torso"})


def resolve_model_dir(name_or_path: str | Path) -> Path:
    """A model folder from a path or a shipped model name (``models/<name>``)."""
    p = Path(name_or_path)
    if (p / "model.json").is_file():
        return p
    shipped = MODELS_DIR / str(name_or_path)
    if (shipped / "model.json").is_file():
        return shipped
    available = sorted(d.name for d in MODELS_DIR.iterdir() if (d / "model.json").is_file()) \
        if MODELS_DIR.is_dir() else []
    raise InputError(f"no model '{name_or_path}' (not a folder with model.json; shipped models: "
                     f"{', '.join(available) or 'none'})", source=str(name_or_path))


def placement_model(group: str | None) -> str | None:
    """The installed motion-mode model for a placement group (:data:`PLACEMENT_MODELS`), or None."""
    name = PLACEMENT_MODELS.get(group or "")
    return name if name is not None and (MODELS_DIR / name / "model.json").is_file() else None
