#!/usr/bin/env python3
"""Local checks of what the release workflow cannot show here (it only runs on GitHub).

1. .github/workflows/release.yml parses and has the expected structure: a build job over
   linux-x64 (manylinux 2_28), windows-x64, macos-arm64 and macos-x64 with their Rust targets
   and runners, maturin's action building core/py, every `uses:` pinned to a version, every
   script a `run:` step calls present in the repository, build_addon.py called with the
   matrix platform, and a release job that needs the build.
2. The per-platform manifest generation (scripts/build_addon.py --manifest-only) for each of
   Blender's platforms: valid TOML, `platforms` = [that platform], one wheel of that platform,
   the template's other keys kept.
3. With --wheel WHEEL: the built wheel is abi3 for CPython 3.11 and, on Linux, manylinux no
   newer than 2_28.

Needs PyYAML (scripts/test.sh installs it). Usage: check_release.py [--wheel WHEEL]
"""

from __future__ import annotations

import argparse
import pathlib
import re
import subprocess
import sys
import tomllib

import yaml

ROOT = pathlib.Path(__file__).resolve().parent.parent
WORKFLOW = ROOT / ".github" / "workflows" / "release.yml"
sys.path.insert(0, str(ROOT / "scripts"))
import build_addon  # noqa: E402  (after the path above)

# Platform → (Rust target, runner prefix) the workflow must build.
EXPECTED = {
    "linux-x64": ("x86_64-unknown-linux-gnu", "ubuntu-"),
    "windows-x64": ("x86_64-pc-windows-msvc", "windows-"),
    "macos-arm64": ("aarch64-apple-darwin", "macos-"),
    "macos-x64": ("x86_64-apple-darwin", "macos-"),
}
NEWEST_GLIBC = (2, 28)


class Checks:
    def __init__(self) -> None:
        self.failures: list[str] = []
        self.passed = 0

    def check(self, ok: bool, what: str) -> bool:
        if ok:
            self.passed += 1
        else:
            self.failures.append(what)
        return ok


def check_workflow(c: Checks) -> None:
    if not c.check(WORKFLOW.is_file(), f"{WORKFLOW.relative_to(ROOT)} exists"):
        return
    wf = yaml.safe_load(WORKFLOW.read_text())
    # YAML 1.1 reads the key `on` as True.
    triggers = wf.get("on", wf.get(True)) or {}
    c.check("push" in triggers and "tags" in (triggers["push"] or {}), "the workflow runs on pushed tags")
    jobs = wf.get("jobs", {})
    c.check(set(jobs) == {"build", "release"}, f"jobs are build and release (got {sorted(jobs)})")
    build = jobs.get("build", {})
    include = build.get("strategy", {}).get("matrix", {}).get("include", [])
    platforms = {e.get("platform"): e for e in include}
    c.check(set(platforms) == set(EXPECTED), f"build matrix platforms {sorted(platforms)} == {sorted(EXPECTED)}")
    for name, (target, runner) in EXPECTED.items():
        e = platforms.get(name, {})
        c.check(e.get("target") == target, f"{name}: target {e.get('target')!r} == {target!r}")
        c.check(str(e.get("runner", "")).startswith(runner), f"{name}: runner {e.get('runner')!r} is {runner}*")
        want = "2_28" if name == "linux-x64" else "off"
        c.check(str(e.get("manylinux")) == want, f"{name}: manylinux {e.get('manylinux')!r} == {want!r}")
    c.check(build.get("runs-on") == "${{ matrix.runner }}", "build runs on the matrix runner")
    steps = build.get("steps", [])
    for job_name, job in jobs.items():
        for step in job.get("steps", []):
            uses = step.get("uses")
            if uses:
                c.check(re.fullmatch(r"[\w.-]+/[\w.-]+@v\d+", uses) is not None,
                        f"{job_name}: '{uses}' is an action pinned to a major version")
            for script in re.findall(r"scripts/[\w./-]+\.(?:py|sh)", step.get("run", "")):
                c.check((ROOT / script).is_file(), f"{job_name}: {script} (called by a run step) exists")
    maturin = [s for s in steps if str(s.get("uses", "")).startswith("PyO3/maturin-action@")]
    if c.check(len(maturin) == 1, "build has one PyO3/maturin-action step"):
        w = maturin[0].get("with", {})
        args = str(w.get("args", ""))
        m = re.search(r"--manifest-path\s+(\S+)", args)
        c.check(m is not None and (ROOT / m.group(1)).is_file(), f"maturin's --manifest-path exists ({args!r})")
        c.check("--release" in args and "--out dist" in args, "maturin builds --release --out dist")
        c.check(w.get("target") == "${{ matrix.target }}", "maturin builds the matrix target")
        c.check(w.get("manylinux") == "${{ matrix.manylinux }}", "maturin uses the matrix manylinux")
    runs = "\n".join(str(s.get("run", "")) for s in steps)
    c.check("scripts/build_addon.py --platform ${{ matrix.platform }}" in runs,
            "build calls scripts/build_addon.py --platform ${{ matrix.platform }}")
    release = jobs.get("release", {})
    c.check(release.get("needs") == "build", "release needs build")
    # The wheel is abi3 (one wheel serves every CPython >= 3.11 Blender ships).
    py_cargo = (ROOT / "core" / "py" / "Cargo.toml").read_text()
    c.check('"abi3-py311"' in py_cargo, "core/py builds an abi3 (py311) extension")


def check_manifests(c: Checks) -> None:
    template = tomllib.loads((ROOT / "addon" / "relume" / "blender_manifest.toml").read_text())
    for platform in build_addon.PLATFORMS:
        out = subprocess.run(
            [sys.executable, str(ROOT / "scripts" / "build_addon.py"), "--manifest-only", "--platform", platform],
            capture_output=True, text=True, check=False)
        if not c.check(out.returncode == 0, f"build_addon.py --manifest-only --platform {platform}: {out.stderr}"):
            continue
        try:
            m = tomllib.loads(out.stdout)
        except tomllib.TOMLDecodeError as e:
            c.check(False, f"{platform}: manifest is not TOML: {e}")
            continue
        c.check(m.get("platforms") == [platform], f"{platform}: platforms = {m.get('platforms')}")
        wheels = m.get("wheels", [])
        c.check(len(wheels) == 1 and wheels[0].startswith("./wheels/") and wheels[0].endswith(".whl"),
                f"{platform}: one bundled wheel ({wheels})")
        if wheels:
            served = build_addon.platform_of(pathlib.PurePosixPath(wheels[0]).name)
            c.check(served == platform, f"{platform}: its wheel {wheels[0]} is for {served}")
        for key in ("schema_version", "id", "version", "type", "blender_version_min", "license", "permissions"):
            c.check(m.get(key) == template.get(key), f"{platform}: {key} kept from the template")
    # The wheels the workflow makes map to their platforms.
    for name, platform in [("relume-0.1.0-cp311-abi3-manylinux_2_28_x86_64.whl", "linux-x64"),
                           ("relume-0.1.0-cp311-abi3-win_amd64.whl", "windows-x64"),
                           ("relume-0.1.0-cp311-abi3-macosx_11_0_arm64.whl", "macos-arm64"),
                           ("relume-0.1.0-cp311-abi3-macosx_10_12_x86_64.whl", "macos-x64")]:
        c.check(build_addon.platform_of(name) == platform, f"{name} is for {platform}")


def check_wheel(c: Checks, wheel: pathlib.Path) -> None:
    name = wheel.name
    parts = name.removesuffix(".whl").split("-")
    c.check(len(parts) == 5 and parts[2] == "cp311" and parts[3] == "abi3", f"{name}: cp311-abi3")
    tags = build_addon.wheel_platform_tags(name)
    print(f"check_release: wheel platform tag(s): {'.'.join(tags)}")
    for tag in tags:
        m = re.fullmatch(r"manylinux_(\d+)_(\d+)_\w+", tag)
        if m:
            glibc = (int(m.group(1)), int(m.group(2)))
            c.check(glibc <= NEWEST_GLIBC, f"{name}: {tag} needs glibc {glibc[0]}.{glibc[1]}, newer than 2.28")
        elif tag.startswith("linux_"):
            c.check(False, f"{name}: {tag} is not a manylinux tag")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wheel", type=pathlib.Path)
    args = ap.parse_args()
    c = Checks()
    check_workflow(c)
    check_manifests(c)
    if args.wheel:
        check_wheel(c, args.wheel)
    for f in c.failures:
        print(f"check_release: FAIL: {f}", file=sys.stderr)
    print(f"check_release: {c.passed} checks passed, {len(c.failures)} failed")
    return 1 if c.failures else 0


if __name__ == "__main__":
    sys.exit(main())
