"""The bpy-free model runtime, imported relative to this add-on.

Installed as an extension, ``model_runtime`` sits beside this package inside
the extension's package; from the repository it is a top-level package. Only
numpy modules are imported here: Blender ships numpy, not torch.
"""

import importlib
from pathlib import Path

_parent = __package__.rpartition(".")[0]
model_runtime = importlib.import_module(f"{_parent}.model_runtime" if _parent else "model_runtime")


def _submodule(name):
    return importlib.import_module(f"{model_runtime.__name__}.{name}")


curve_geometry = _submodule("curve_geometry")
skeleton = _submodule("skeleton")
numpy_model = _submodule("numpy_model")
retarget = _submodule("retarget")
shot = _submodule("shot")
profiles = _submodule("data.profiles")
ASSETS = Path(model_runtime.__file__).resolve().parents[1] / "assets"
