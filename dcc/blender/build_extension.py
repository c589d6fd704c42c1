"""Builds the Blender extension zip: the add-on with the tessera wheel inside (Blender
installs an extension's wheels into its own Python).

    python3 dcc/blender/build_extension.py [OUT_DIR]      # default: out/

Then in Blender: Edit > Preferences > Get Extensions > Install from Disk, and pick the zip.
"""

import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def build(out_dir: Path) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", tmp, str(ROOT / "python")], check=True)
        wheel = next(Path(tmp).glob("tessera-*.whl"))
        manifest = (HERE / "tessera_blender" / "blender_manifest.toml").read_text()
        # Top-level keys go before the first table ([permissions]).
        manifest = manifest.replace("[permissions]", f'wheels = ["./wheels/{wheel.name}"]\n\n[permissions]', 1)
        version = next(line.split('"')[1] for line in manifest.splitlines() if line.startswith("version"))
        target = out_dir / f"tessera_blender-{version}.zip"
        with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as z:
            for source in sorted((HERE / "tessera_blender").glob("*.py")):
                z.write(source, source.name)
            z.writestr("blender_manifest.toml", manifest)
            z.write(wheel, f"wheels/{wheel.name}")
    return target


if __name__ == "__main__":
    print(build(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "out"))
    shutil.rmtree(HERE / "tessera_blender" / "__pycache__", ignore_errors=True)
