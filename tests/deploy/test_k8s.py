"""docker/k8s/*.yaml: the manifests parse, fit together and match the service."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any
from urllib.parse import urlsplit

import pytest

from efdm_cli import serve
from tests.deploy._files import (
    K8S,
    SERVICE_PORT,
    SERVICE_UID,
    container,
    dockerfile_instructions,
    env_pairs,
    load_yaml,
    load_yaml_all,
    settings_from_env,
)

NAME = "efdm-tracker"


@pytest.fixture(scope="module")
def docs() -> list[Any]:
    found = []
    for path in sorted(K8S.glob("*.yaml")):
        if path.name == "kustomization.yaml":
            continue
        for doc in load_yaml_all(path):
            assert isinstance(doc, dict), path
            assert {"apiVersion", "kind", "metadata"} <= doc.keys(), path
            found.append(doc)
    return found


def one(docs: list[Any], kind: str, name: str = NAME) -> Any:
    matches = [d for d in docs if d["kind"] == kind and d["metadata"]["name"] == name]
    assert len(matches) == 1, f"{kind}/{name}: {len(matches)} found"
    return matches[0]


def probes(c: Any) -> Iterator[tuple[str, Any]]:
    for key in ("startupProbe", "livenessProbe", "readinessProbe"):
        if key in c:
            yield key, c[key]


def test_expected_kinds(docs: list[Any]) -> None:
    kinds = {(d["kind"], d["metadata"]["name"]) for d in docs}
    for kind in ("Deployment", "Service", "HorizontalPodAutoscaler", "Ingress", "ConfigMap"):
        assert (kind, NAME) in kinds, kind
    assert ("Deployment", "redis") in kinds
    assert ("Service", "redis") in kinds
    assert "managed Redis" in (K8S / "redis.yaml").read_text(encoding="utf-8")


def test_kustomization_lists_every_manifest() -> None:
    kustomization = load_yaml(K8S / "kustomization.yaml")
    files = {p.name for p in K8S.glob("*.yaml")} - {"kustomization.yaml"}
    assert set(kustomization["resources"]) == files


def test_deployment_probes_port_and_labels(docs: list[Any]) -> None:
    deployment = one(docs, "Deployment")
    spec = deployment["spec"]
    labels = spec["template"]["metadata"]["labels"]
    assert spec["selector"]["matchLabels"].items() <= labels.items()
    c = container(deployment)
    ports = {p["name"]: p["containerPort"] for p in c["ports"]}
    assert ports == {"http": SERVICE_PORT}
    paths = {key: p["httpGet"]["path"] for key, p in probes(c)}
    assert paths["livenessProbe"] == "/healthz"
    assert paths["readinessProbe"] == "/readyz"
    assert paths.get("startupProbe", "/healthz") == "/healthz"
    for key, probe in probes(c):
        assert probe["httpGet"]["port"] in {"http", SERVICE_PORT}, key


def test_deployment_resources_shutdown_and_security(docs: list[Any]) -> None:
    pod = one(docs, "Deployment")["spec"]["template"]["spec"]
    c = container(one(docs, "Deployment"))
    for kind in ("requests", "limits"):
        assert {"cpu", "memory"} <= c["resources"][kind].keys(), kind
    command = c["lifecycle"]["preStop"]["exec"]["command"]
    assert command[0] == "sleep"
    # preStop, then uvicorn's graceful shutdown (engine/cli/serve.py), within the grace period
    grace = getattr(serve, "GRACE_SECONDS", 10)
    assert pod["terminationGracePeriodSeconds"] >= int(command[1]) + grace
    security = pod["securityContext"]
    assert security["runAsNonRoot"] is True
    assert security["runAsUser"] == SERVICE_UID  # the image's USER
    assert c["securityContext"]["allowPrivilegeEscalation"] is False
    assert c["securityContext"]["capabilities"]["drop"] == ["ALL"]


def test_read_only_root_keeps_numba_cache_and_tmp_writable(docs: list[Any]) -> None:
    c = container(one(docs, "Deployment"))
    assert c["securityContext"]["readOnlyRootFilesystem"] is True
    mounts = [m["mountPath"] for m in c["volumeMounts"]]
    image_env: dict[str, str] = {}
    for i in dockerfile_instructions():
        if i.keyword == "ENV":
            image_env.update(env_pairs(i))
    env = {e["name"]: e["value"] for e in c.get("env", [])}
    cache = env.get("NUMBA_CACHE_DIR", image_env["NUMBA_CACHE_DIR"])
    assert any(cache.startswith(m.rstrip("/") + "/") for m in mounts), (cache, mounts)
    assert "/tmp" in mounts


def test_configmap_holds_valid_settings_matching_the_deployment(docs: list[Any]) -> None:
    config = one(docs, "ConfigMap")
    data = {k: str(v) for k, v in config["data"].items()}
    settings = settings_from_env(data)  # unknown EFDM_ names or bad values fail here
    assert settings.host == "0.0.0.0"
    assert settings.port == SERVICE_PORT
    c = container(one(docs, "Deployment"))
    refs = [e["configMapRef"]["name"] for e in c["envFrom"] if "configMapRef" in e]
    assert refs == [NAME]
    for e in c.get("env", []):
        if e["name"].startswith("EFDM_"):
            settings_from_env({e["name"]: e["value"]})
    # EFDM_REDIS_URL names the Redis Service and its port
    url = urlsplit(settings.redis_url or "")
    redis = one(docs, "Service", "redis")
    assert url.hostname == "redis"
    assert url.port in {p["port"] for p in redis["spec"]["ports"]}
    cpu_limit = str(c["resources"]["limits"]["cpu"])
    if settings.workers and not cpu_limit.endswith("m"):
        assert settings.workers <= int(float(cpu_limit)), "more tracking threads than CPUs"


def test_services_select_their_pods_and_ports(docs: list[Any]) -> None:
    for name in (NAME, "redis"):
        service = one(docs, "Service", name)
        deployment = one(docs, "Deployment", name)
        labels = deployment["spec"]["template"]["metadata"]["labels"]
        assert service["spec"]["selector"].items() <= labels.items(), name
        c = container(deployment)
        by_name = {p["name"]: p["containerPort"] for p in c["ports"]}
        for port in service["spec"]["ports"]:
            target = port["targetPort"]
            assert target in by_name or target in by_name.values(), (name, target)


def test_hpa_scales_the_deployment_on_cpu(docs: list[Any]) -> None:
    hpa = one(docs, "HorizontalPodAutoscaler")
    assert hpa["apiVersion"] == "autoscaling/v2"
    target = hpa["spec"]["scaleTargetRef"]
    assert (target["kind"], target["name"]) == ("Deployment", NAME)
    assert 1 <= hpa["spec"]["minReplicas"] <= hpa["spec"]["maxReplicas"]
    metrics = [m["resource"]["name"] for m in hpa["spec"]["metrics"] if m["type"] == "Resource"]
    assert "cpu" in metrics


def test_ingress_reaches_the_service_with_websocket_timeouts(docs: list[Any]) -> None:
    ingress = one(docs, "Ingress")
    annotations = ingress["metadata"]["annotations"]
    for key in ("proxy-read-timeout", "proxy-send-timeout"):
        assert int(annotations[f"nginx.ingress.kubernetes.io/{key}"]) >= 3600, key
    service = one(docs, "Service")
    port_names = {p["name"] for p in service["spec"]["ports"]}
    port_numbers = {p["port"] for p in service["spec"]["ports"]}
    for rule in ingress["spec"]["rules"]:
        for path in rule["http"]["paths"]:
            backend = path["backend"]["service"]
            assert backend["name"] == NAME
            port = backend["port"]
            assert port.get("name") in port_names or port.get("number") in port_numbers
