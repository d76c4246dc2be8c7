"""docker/compose.yaml and docker/nginx.conf: Redis, two or more replicas, nginx in front."""

from __future__ import annotations

import re
from typing import Any
from urllib.parse import urlsplit

import pytest

from tests.deploy._files import (
    COMPOSE,
    DOCKER,
    NGINX,
    ROOT,
    SERVICE_PORT,
    interpolate,
    load_yaml,
    settings_from_env,
)


@pytest.fixture(scope="module")
def compose() -> Any:
    doc = load_yaml(COMPOSE)
    assert isinstance(doc, dict)
    return doc


def efdm_services(compose: Any) -> dict[str, Any]:
    """The replicas of the service: those built from docker/Dockerfile."""
    return {
        name: svc
        for name, svc in compose["services"].items()
        if isinstance(svc.get("build"), dict)
        and svc["build"].get("dockerfile") == "docker/Dockerfile"
    }


def environment(service: Any) -> dict[str, str]:
    env = service.get("environment", {})
    if isinstance(env, list):  # ["KEY=value", ...]
        env = dict(item.split("=", 1) for item in env)
    return {k: interpolate(str(v)) for k, v in env.items()}


def nginx_conf() -> str:
    return re.sub(r"#[^\n]*", "", NGINX.read_text(encoding="utf-8"))


def seconds(value: str) -> float:
    """An nginx time (``3600``, ``3600s``, ``60m``, ``1h``) in seconds."""
    match = re.fullmatch(r"(\d+)(ms|s|m|h|d)?", value)
    assert match, value
    scale = {"ms": 0.001, "s": 1, "m": 60, "h": 3600, "d": 86400}[match.group(2) or "s"]
    return int(match.group(1)) * scale


def test_redis_with_a_ping_healthcheck(compose: Any) -> None:
    redis = compose["services"]["redis"]
    assert redis["image"].startswith("redis:")
    test = redis["healthcheck"]["test"]
    assert test[0] in {"CMD", "CMD-SHELL"}
    assert "redis-cli" in " ".join(test)
    assert "ping" in " ".join(test)


def test_at_least_two_replicas_share_redis(compose: Any) -> None:
    replicas = efdm_services(compose)
    assert len(replicas) >= 2, sorted(compose["services"])
    for name, svc in replicas.items():
        build = svc["build"]
        assert (COMPOSE.parent / build["context"] / build["dockerfile"]).resolve() == (
            ROOT / "docker" / "Dockerfile"
        ), name
        url = urlsplit(environment(svc)["EFDM_REDIS_URL"])
        assert url.scheme == "redis"
        assert url.hostname in compose["services"], f"{name}: {url.hostname} is not a service"
        assert (url.port or 6379) == 6379
        assert svc["depends_on"][url.hostname]["condition"] == "service_healthy"
        assert "test" in svc["healthcheck"]


def test_every_efdm_variable_is_a_valid_setting(compose: Any) -> None:
    for svc in compose["services"].values():
        env = environment(svc)
        if any(k.startswith("EFDM_") for k in env):
            settings = settings_from_env(env)  # unknown names or bad values fail here
            assert settings.redis_url


def test_replica_healthchecks_are_valid_python_on_the_service_port(compose: Any) -> None:
    for name, svc in efdm_services(compose).items():
        test = svc["healthcheck"]["test"]
        assert test[:3] == ["CMD", "python", "-c"], name
        compile(test[3], f"<{name} healthcheck>", "exec")
        assert f"127.0.0.1:{SERVICE_PORT}/" in test[3]
        assert "/healthz" in test[3] or "/readyz" in test[3]


def test_nginx_in_front_waits_for_healthy_replicas(compose: Any) -> None:
    lbs = [s for s in compose["services"].values() if str(s.get("image", "")).startswith("nginx")]
    assert len(lbs) == 1
    lb = lbs[0]
    mounts = [str(v).split(":") for v in lb["volumes"]]
    assert any(
        (DOCKER / src).resolve() == NGINX and dst.startswith("/etc/nginx/")
        for src, dst, *_ in mounts
    )
    for name in efdm_services(compose):
        assert lb["depends_on"][name]["condition"] == "service_healthy"
    assert lb["ports"], "the balancer is the published entry point"
    for name, svc in efdm_services(compose).items():
        assert "ports" not in svc, f"{name} is published: clients should go through nginx"


def test_nginx_upstream_lists_every_replica(compose: Any) -> None:
    conf = nginx_conf()
    upstream = re.search(r"upstream\s+(\w+)\s*\{(.*?)\}", conf, re.S)
    assert upstream, "no upstream block"
    servers = re.findall(r"^\s*server\s+([\w.-]+):(\d+)", upstream.group(2), re.M)
    assert sorted(servers) == sorted((n, str(SERVICE_PORT)) for n in efdm_services(compose))
    assert re.search(rf"proxy_pass\s+http://{upstream.group(1)}\s*;", conf)


def test_nginx_passes_websockets_with_long_timeouts() -> None:
    conf = nginx_conf()
    assert re.search(r"proxy_http_version\s+1\.1\s*;", conf)
    assert re.search(r"proxy_set_header\s+Upgrade\s+\$http_upgrade\s*;", conf)
    connection = re.search(r"proxy_set_header\s+Connection\s+\$(\w+)\s*;", conf)
    assert connection, "Connection header"
    assert re.search(rf"map\s+\$http_upgrade\s+\${connection.group(1)}\s*\{{", conf)
    for directive in ("proxy_read_timeout", "proxy_send_timeout"):
        value = re.search(rf"{directive}\s+(\S+)\s*;", conf)
        assert value, directive
        assert seconds(value.group(1)) >= 3600, f"{directive} {value.group(1)}"


def test_nginx_affinity_by_session_id_and_frame_sized_bodies() -> None:
    conf = nginx_conf()
    hashed = re.search(r"hash\s+\$(\w+)\s+consistent\s*;", conf)
    assert hashed, "hash ... consistent"
    mapping = re.search(rf"map\s+\$uri\s+\${hashed.group(1)}\s*\{{(.*?)\}}", conf, re.S)
    assert mapping, f"${hashed.group(1)} is not mapped from $uri"
    regex = re.search(r'"~(\^/v1/sessions/[^"]+)"', mapping.group(1))
    assert regex
    pattern = re.compile(regex.group(1).replace("(?<", "(?P<"))
    match = pattern.match("/v1/sessions/0f3a9c/stream")
    assert match
    assert "0f3a9c" in match.groups()
    size = re.search(r"client_max_body_size\s+(\d+)([km]?)\s*;", conf)
    assert size
    limit = int(size.group(1)) * {"": 1, "k": 1024, "m": 1024**2}[size.group(2)]
    assert limit >= settings_from_env({}).max_frame_bytes
