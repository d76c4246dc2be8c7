"""The deployment files under test, and small readers for them (YAML, Dockerfile, settings)."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from service.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
DOCKER = ROOT / "docker"
DOCKERFILE = DOCKER / "Dockerfile"
DOCKERIGNORE = ROOT / ".dockerignore"
COMPOSE = DOCKER / "compose.yaml"
NGINX = DOCKER / "nginx.conf"
K8S = DOCKER / "k8s"
SCRIPT = DOCKER / "test-container.sh"
CONTAINERS_CONF = DOCKER / "containers.conf"

SERVICE_PORT = 8000
SERVICE_UID = 10001


def settings_env_names() -> set[str]:
    """Every ``EFDM_*`` variable the service reads (one per ``Settings`` field)."""
    return {f"EFDM_{name.upper()}" for name in Settings.model_fields}


def settings_from_env(env: dict[str, str]) -> Settings:
    """Validate the ``EFDM_*`` values of ``env`` as the service would (unknown names raise)."""
    known = settings_env_names()
    unknown = sorted(k for k in env if k.startswith("EFDM_") and k not in known)
    assert not unknown, f"not settings of service/settings.py: {unknown}"
    values = {k.removeprefix("EFDM_").lower(): v for k, v in env.items() if k.startswith("EFDM_")}
    return Settings.model_validate(values)


def load_yaml(path: Path) -> Any:
    """One YAML document."""
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def load_yaml_all(path: Path) -> list[Any]:
    """Every non-empty document of a multi-document YAML file."""
    return [d for d in yaml.safe_load_all(path.read_text(encoding="utf-8")) if d is not None]


_INTERPOLATION = re.compile(r"\$\{(?P<name>[A-Za-z_][A-Za-z0-9_]*)(?::?-(?P<default>[^}]*))?\}")


def interpolate(value: str) -> str:
    """Compose's ``${NAME:-default}`` with nothing set: the default (or empty)."""
    return _INTERPOLATION.sub(lambda m: m.group("default") or "", value)


@dataclass(frozen=True)
class Instruction:
    """One Dockerfile instruction: keyword (upper case), arguments, build stage index."""

    keyword: str
    args: str
    stage: int

    def json_args(self) -> list[str] | None:
        """The exec-form (JSON array) arguments, or None for the shell form."""
        try:
            value = json.loads(self.args)
        except json.JSONDecodeError:
            return None
        if isinstance(value, list) and all(isinstance(v, str) for v in value):
            return value
        return None


def dockerfile_instructions(path: Path = DOCKERFILE) -> list[Instruction]:
    """Instructions with continuation lines joined and comments dropped; stage -1 before FROM."""
    logical: list[str] = []
    current = ""
    for raw in path.read_text(encoding="utf-8").splitlines():
        line = raw.strip()
        if not current and (not line or line.startswith("#")):
            continue
        if current and line.startswith("#"):
            continue  # a comment inside a continued instruction
        if line.endswith("\\"):
            current += line[:-1].rstrip() + " "
            continue
        logical.append(current + line)
        current = ""
    assert not current, "the Dockerfile ends inside a continued instruction"
    instructions: list[Instruction] = []
    stage = -1
    for text in logical:
        keyword, _, args = text.partition(" ")
        keyword = keyword.upper()
        if keyword == "FROM":
            stage += 1
        instructions.append(Instruction(keyword, args.strip(), stage))
    return instructions


def env_pairs(instruction: Instruction) -> dict[str, str]:
    """``ENV a=1 b=2`` (the key=value form) as a dict."""
    pairs: dict[str, str] = {}
    for token in instruction.args.split():
        key, sep, value = token.partition("=")
        assert sep, f"ENV {instruction.args!r}: use the key=value form"
        pairs[key] = value.strip('"')
    return pairs


def container(doc: Any, name: str | None = None) -> Any:
    """The (first, or named) container of a Deployment."""
    containers = doc["spec"]["template"]["spec"]["containers"]
    if name is None:
        return containers[0]
    return next(c for c in containers if c["name"] == name)
