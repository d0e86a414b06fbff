"""Fixtures of the Blender tests: the BUILT extension zip, installed offline into headless bpy.

* A temporary ``BLENDER_USER_RESOURCES`` directory is set before ``bpy`` is imported, so the
  extension (and its wheel) is installed there and nothing leaks into the user's Blender.
* The extension zip is ``dist/bidegree-*.zip`` when it is newer than every source file, else it
  is built once per session with ``BIDEGREE_NO_ZIG=1 packaging/build.sh``.
* The tests use the installed copy: the extension's wheel ``site-packages`` comes first on
  ``sys.path`` and ``bidegree_blender`` is imported from there.

Run these tests in their own pytest process (``pytest tests/blender``): ``bidegree`` is a native
module that can only be initialised once per process, so if another test imported it first from
the source tree, the installed wheel's copy cannot be loaded.
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
DIST = ROOT / "dist"
EXTENSION_ID = "bidegree"
ADDON_MODULE = f"bl_ext.user_default.{EXTENSION_ID}"

#: Set by the ``addon`` fixture: ``bidegree`` had been imported (by other tests of this process,
#: from the source tree) before the extension was installed, so the installed wheel's native
#: module cannot be loaded any more (see the docstring).
_STATE = {"bidegree_preimported": False}

_USER_DIR = tempfile.mkdtemp(prefix="bidegree-blender-user-")
os.environ["BLENDER_USER_RESOURCES"] = _USER_DIR
_SITE = Path(_USER_DIR, "extensions", ".local", "lib", "python3.11", "site-packages")
# Exists before bpy starts, so Blender puts it *before* the venv's site-packages on sys.path.
_SITE.mkdir(parents=True, exist_ok=True)

bpy = pytest.importorskip("bpy")


def _newest_source_mtime() -> float:
    patterns = [
        "addon/bidegree/**/*",
        "native/python/python/**/*.py",
        "native/python/src/**/*.rs",
        "native/python/Cargo.toml",
        "native/python/pyproject.toml",
        "native/core/src/**/*.rs",
        "native/core/Cargo.toml",
        "packaging/build.sh",
    ]
    newest = 0.0
    for pattern in patterns:
        for path in glob.glob(str(ROOT / pattern), recursive=True):
            if os.path.isfile(path) and "__pycache__" not in path:
                newest = max(newest, os.path.getmtime(path))
    return newest


def _extension_zip() -> Path:
    zips = sorted(DIST.glob(f"{EXTENSION_ID}-*.zip"), key=os.path.getmtime)
    if zips and os.path.getmtime(zips[-1]) >= _newest_source_mtime():
        return zips[-1]
    env = dict(os.environ, BIDEGREE_NO_ZIG="1")
    env.pop("BLENDER_USER_RESOURCES", None)
    proc = subprocess.run(
        ["bash", str(ROOT / "packaging" / "build.sh")],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        pytest.fail(f"packaging/build.sh failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}")
    zips = sorted(DIST.glob(f"{EXTENSION_ID}-*.zip"), key=os.path.getmtime)
    assert zips, "packaging/build.sh produced no extension zip"
    return zips[-1]


@pytest.fixture(scope="session")
def extension_zip() -> Path:
    """The built extension zip (fresh from dist/ or built now)."""
    return _extension_zip()


@pytest.fixture(scope="session")
def addon(extension_zip: Path) -> Iterator[ModuleType]:
    """Install + enable the built extension offline and return its (installed) module."""
    _STATE["bidegree_preimported"] = "bidegree" in sys.modules
    for name in [
        m for m in sys.modules if m == "bidegree_blender" or m.startswith("bidegree_blender.")
    ]:
        del sys.modules[name]
    result = bpy.ops.extensions.package_install_files(
        filepath=str(extension_zip), repo="user_default", enable_on_install=True
    )
    assert result == {"FINISHED"}, result
    module = sys.modules.get(ADDON_MODULE)
    assert module is not None, (
        f"{ADDON_MODULE} not enabled after install ({sorted(sys.modules)[:5]})"
    )
    if str(_SITE) in sys.path:
        sys.path.remove(str(_SITE))
    sys.path.insert(0, str(_SITE))
    yield module
    # A Python-defined render engine left registered crashes bpy 4.2 at exit.
    util = sys.modules.get("util")
    if util is not None and util.Probe.engine is not None:
        bpy.utils.unregister_class(util.Probe.engine)
        util.Probe.engine = None
    bpy.ops.preferences.addon_disable(module=ADDON_MODULE)
    shutil.rmtree(_USER_DIR, ignore_errors=True)


@pytest.fixture(autouse=True)
def _installed_modules(request: pytest.FixtureRequest, addon: ModuleType) -> None:
    """Give a test module's ``bidegree``, ``bidegree_blender`` and ``modifier`` globals the
    installed extension's copies (imported only after it was installed)."""
    import bidegree
    import bidegree_blender
    from bidegree_blender import modifier

    for name, module in (
        ("bidegree", bidegree),
        ("bidegree_blender", bidegree_blender),
        ("modifier", modifier),
    ):
        if hasattr(request.module, name):
            setattr(request.module, name, module)


@pytest.fixture(scope="session")
def bidegree_preimported(addon: ModuleType) -> bool:
    """Whether ``bidegree`` was imported (from elsewhere) before the extension was installed."""
    return _STATE["bidegree_preimported"]


@pytest.fixture(scope="session")
def user_dir() -> str:
    """The temporary Blender user resources directory of this session."""
    return _USER_DIR


@pytest.fixture
def scene(addon: ModuleType) -> Iterator[Any]:
    """The current scene, emptied of objects and meshes before and after the test."""

    from bidegree_blender import modifier

    def clear() -> None:
        for collection in (
            bpy.data.objects,
            bpy.data.meshes,
            bpy.data.materials,
            bpy.data.node_groups,
            bpy.data.armatures,
            bpy.data.actions,
            bpy.data.cameras,
            bpy.data.textures,
        ):
            for item in list(collection):
                collection.remove(item)
        for child in list(bpy.context.scene.collection.children):
            bpy.data.collections.remove(child)
        bpy.context.scene.frame_set(1)
        modifier.reset()

    clear()
    yield bpy.context.scene
    clear()


_EXIT: dict[str, int] = {}


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Remember the exit status for :func:`pytest_unconfigure`."""
    _EXIT["status"] = int(exitstatus)


def pytest_unconfigure(config: pytest.Config) -> None:
    """bpy 4.2 can segfault while Python shuts down after a session that rendered with a
    Python-defined engine (each test file alone exits cleanly): leave without bpy's teardown,
    with pytest's own exit status, once everything has been reported."""
    if bpy.app.version < (5, 0, 0) and "status" in _EXIT:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_EXIT["status"])
