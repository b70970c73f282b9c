"""The extension zip, built and validated by Blender's own tool, installs and works."""

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import bpy
import pytest

ROOT = Path(__file__).resolve().parents[1]
BLENDER_EXT = Path(bpy.utils.system_resource('SCRIPTS')) / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"

INSTALL_SCRIPT = """
import sys, bpy
sys.modules["torch"] = None  # a stock Blender has no torch: importing it must not be needed
bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default", enable_on_install=True)
extension = sys.modules["bl_ext.user_default.trajevae"]
api = extension.trajevae_addon.api
rig = extension.trajevae_addon.mannequin.build_mannequin(bpy.context.scene)
bpy.context.scene.frame_end = 20
mapping = api.map_rig(rig)
made = api.generate_variants(rig, n=2)
print("API", api.__name__, mapping["LWrist"], len(made), hasattr(bpy.types, "TRAJEVAE_OT_generate"))
"""

DAMAGED_WEIGHTS_SCRIPT = """
import sys, bpy
from pathlib import Path
bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default", enable_on_install=True)
extension = sys.modules["bl_ext.user_default.trajevae"]
addon = extension.trajevae_addon
assets = Path(extension.__file__).parent / "assets"
rig = addon.mannequin.build_mannequin(bpy.context.scene)
bpy.context.scene.frame_end = 20
bpy.context.view_layer.objects.active = rig
rig.trajevae.variant_count = 2
(assets / "sampler.npz").unlink()
print("SAMPLER", bpy.ops.trajevae.generate(), rig.trajevae.last_report)
bpy.ops.trajevae.discard_variants()
model = assets / "trajevae.npz"
model.write_bytes(model.read_bytes()[: model.stat().st_size // 2])
addon.inference.release()
try:
    bpy.ops.trajevae.generate()
except RuntimeError as error:
    print("MODEL", str(error).strip(), len(bpy.data.actions))
"""


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    out = tmp_path_factory.mktemp("package")
    subprocess.run([sys.executable, str(BLENDER_EXT), "build", "--source-dir", str(ROOT), "--output-dir", str(out)],
                   check=True, capture_output=True)
    (zip_path,) = out.glob("trajevae-*.zip")
    return zip_path


def test_blender_validates_the_zip_and_it_holds_the_runtime_not_the_tests(package):
    result = subprocess.run([sys.executable, str(BLENDER_EXT), "validate", str(package)], capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    names = zipfile.ZipFile(package).namelist()
    for needed in ("blender_manifest.toml", "__init__.py", "trajevae_addon/api.py", "model_runtime/numpy_model.py",
                   "model_runtime/generation.py", "assets/trajevae.npz"):
        assert needed in names
    assert not [n for n in names if n.startswith(("tests/", "benchmarks/", ".")) or "__pycache__" in n]


def test_installed_extension_enables_and_its_api_generates_without_torch(package, tmp_path):
    environment = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path))
    result = subprocess.run([sys.executable, "-c", INSTALL_SCRIPT, str(package)], capture_output=True, text=True,
                            env=environment, cwd=tmp_path, timeout=300)
    line = next((l for l in result.stdout.splitlines() if l.startswith("API ")), None)
    assert line == "API bl_ext.user_default.trajevae.trajevae_addon.api LWrist 2 True", result.stdout + result.stderr


def test_installed_extension_says_which_weights_are_missing_or_damaged(package, tmp_path):
    environment = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path))
    result = subprocess.run([sys.executable, "-c", DAMAGED_WEIGHTS_SCRIPT, str(package)], capture_output=True,
                            text=True, env=environment, cwd=tmp_path, timeout=300)
    lines = {line.split(" ", 1)[0]: line for line in result.stdout.splitlines() if line.startswith(("SAMPLER", "MODEL"))}
    assert "SAMPLER {'FINISHED'}" in lines.get("SAMPLER", ""), result.stdout + result.stderr
    assert "sampler.npz" in lines["SAMPLER"] and "missing" in lines["SAMPLER"]
    model = lines.get("MODEL", "")
    assert "trajevae.npz" in model and "reinstall the TrajeVAE extension" in model, result.stdout + result.stderr
    assert model.endswith(" 0") and "Traceback" not in result.stderr
