"""The Open Inference Protocol's reference client, tritonclient, unmodified, against the real
server over HTTP and gRPC: health, metadata, versions, inference with JSON and with binary
tensor data, the outputs filter, errors, and a model swap during traffic.

    pip install 'tritonclient[http,grpc]' pytest
    python3 -m pytest -q tests/clients        # BIN=path/to/reflectance to test a given binary
"""

import base64
import json
import os
import pathlib
import shutil
import socket
import subprocess
import threading
import time
import urllib.request

import numpy as np
import pytest
import tritonclient.grpc as grpcclient
import tritonclient.http as httpclient
from tritonclient.utils import InferenceServerException

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = os.environ.get("BIN", str(ROOT / "target" / "release" / "reflectance"))
FIXTURE = ROOT / "tests" / "fixtures" / "features" / "sphere_rgb8.png"
# The committed fixture's circle and white (README's first classification): ward6 says chrome.
CIRCLE = {"white": 0.8, "cx": 96.5, "cy": 94.25, "r": 85.0}
TOKEN = "a-token-for-the-client-tests-0123456789"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """The shipped ward6, and `demo` (two versions trained on the committed feature table,
    version 1 active), served with gRPC and the admin plane on."""
    work = tmp_path_factory.mktemp("clients")
    models = work / "models"
    shutil.copytree(ROOT / "models" / "ward6" / "1", models / "ward6" / "1")
    for _ in range(2):
        subprocess.run([BIN, "train", "--table", str(ROOT / "tests/fixtures/learn/table.csv"),
                        "--features", "hand6", "--models", str(models), "--name", "demo",
                        "--no-cv"], check=True, stdout=subprocess.DEVNULL)
    (models / "demo" / "ACTIVE").write_text("1\n")
    ports = {k: free_port() for k in ("http", "grpc", "admin")}
    env = dict(os.environ, REFLECTANCE_ADMIN_TOKEN=TOKEN)
    process = subprocess.Popen(
        [BIN, "serve", "--models", str(models), "--default-model", "ward6",
         "--listen", f"127.0.0.1:{ports['http']}", "--grpc-listen", f"127.0.0.1:{ports['grpc']}",
         "--admin-listen", f"127.0.0.1:{ports['admin']}", "--data-dir", str(work / "data"),
         "--log-format", "text", "--log", "warn"],
        env=env, stderr=subprocess.PIPE)
    http = httpclient.InferenceServerClient(f"127.0.0.1:{ports['http']}")
    deadline = time.time() + 60
    while True:
        try:
            if http.is_server_ready():
                break
        except Exception:
            pass
        if process.poll() is not None or time.time() > deadline:
            raise RuntimeError(process.stderr.read().decode() if process.stderr else "no server")
        time.sleep(0.1)
    urls = {f"{k}_url": f"127.0.0.1:{ports[k]}" for k in ("http", "grpc")}
    yield {"http": http, "grpc": grpcclient.InferenceServerClient(urls["grpc_url"]),
           "admin": f"http://127.0.0.1:{ports['admin']}", **urls}
    process.terminate()
    process.wait(timeout=30)


def inputs(module, binary=True, image=None):
    """The fixture's inputs, built as a tritonclient user builds them."""
    image = FIXTURE.read_bytes() if image is None else image
    if module is httpclient and not binary:
        # JSON carries BYTES as text: the file travels base64.
        image = base64.b64encode(image)
    tensors = [("image", np.array([image], dtype=np.object_), "BYTES")]
    tensors += [(k, np.array([v], dtype=np.float64), "FP64") for k, v in CIRCLE.items()]
    return built(module, tensors, binary)


def built(module, tensors, binary=True):
    """(name, array, datatype) as the client's InferInputs."""
    out = []
    for name, array, datatype in tensors:
        tensor = module.InferInput(name, list(array.shape), datatype)
        if module is httpclient:
            tensor.set_data_from_numpy(array, binary_data=binary)
        else:
            tensor.set_data_from_numpy(array)
        out.append(tensor)
    return out


def check_answer(result):
    assert result.as_numpy("label").tolist() == [b"chrome"]
    p = result.as_numpy("probabilities")
    assert p.shape == (6,) and abs(p.sum() - 1.0) < 1e-9
    assert result.as_numpy("classes").tolist()[int(np.argmax(p))] == b"chrome"
    assert result.as_numpy("prediction_set").tolist()[0] == b"chrome"
    assert result.as_numpy("in_domain").dtype == np.bool_
    ward = result.as_numpy("ward")
    assert ward.shape == (3, 3) and np.all(ward[:, 1] <= ward[:, 0]) and np.all(ward[:, 0] <= ward[:, 2])


def test_health_and_metadata(server):
    for transport in ("http", "grpc"):
        client = server[transport]
        assert client.is_server_live() and client.is_server_ready()
        assert client.is_model_ready("ward6") and client.is_model_ready("ward6", "1")
        assert client.is_model_ready("demo", "2")
        assert not client.is_model_ready("demo", "3")
        assert not client.is_model_ready("nope")
    meta = server["http"].get_server_metadata()
    assert meta["name"] == "reflectance" and "binary_tensor_data" in meta["extensions"]
    assert server["grpc"].get_server_metadata().name == "reflectance"
    http_meta = server["http"].get_model_metadata("demo")
    grpc_meta = server["grpc"].get_model_metadata("demo", "2", as_json=True)
    assert http_meta["versions"] == grpc_meta["versions"] == ["1", "2"]
    assert [t["name"] for t in http_meta["inputs"]] == [t["name"] for t in grpc_meta["inputs"]]
    assert {"image", "white", "cx", "cy", "r"} <= {t["name"] for t in http_meta["inputs"]}
    ward6 = server["http"].get_model_metadata("ward6", "1")
    assert [o["name"] for o in ward6["outputs"]][:5] == [
        "label", "probabilities", "classes", "prediction_set", "in_domain"]


@pytest.mark.parametrize("binary", [True, False])
def test_http_infer(server, binary):
    client = server["http"]
    result = client.infer("ward6", inputs(httpclient, binary))
    check_answer(result)
    assert result.get_response()["model_version"] == "1"
    # The outputs filter, one output as JSON and one as binary data.
    outputs = [httpclient.InferRequestedOutput("label", binary_data=False),
               httpclient.InferRequestedOutput("probabilities", binary_data=True)]
    result = client.infer("ward6", inputs(httpclient, binary), outputs=outputs, model_version="1",
                          request_id="r-1")
    response = result.get_response()
    assert [o["name"] for o in response["outputs"]] == ["label", "probabilities"]
    assert response["id"] == "r-1"
    assert response["outputs"][0]["data"] == ["chrome"]
    assert result.as_numpy("probabilities").shape == (6,)


@pytest.mark.parametrize("compression", ["gzip", "deflate"])
def test_http_compressed_request(server, compression):
    result = server["http"].infer("ward6", inputs(httpclient), request_compression_algorithm=compression)
    check_answer(result)


def test_grpc_infer(server):
    client = server["grpc"]
    check_answer(client.infer("ward6", inputs(grpcclient)))
    result = client.infer("ward6", inputs(grpcclient), model_version="1", request_id="g-1",
                          outputs=[grpcclient.InferRequestedOutput("label")])
    response = result.get_response(as_json=True)
    assert [o["name"] for o in response["outputs"]] == ["label"]
    assert response["id"] == "g-1" and response["model_version"] == "1"
    assert result.as_numpy("label").tolist() == [b"chrome"]


@pytest.mark.parametrize("transport", ["http", "grpc"])
def test_errors_carry_the_message(server, transport):
    module = httpclient if transport == "http" else grpcclient
    client = server[transport]
    cases = [
        (lambda: client.infer("nope", inputs(module)), "unknown model"),
        (lambda: client.infer("ward6", inputs(module), model_version="9"), "no version"),
        (lambda: client.infer("ward6", inputs(module)[1:]), "image"),
        (lambda: client.infer("ward6", inputs(module, image=b"not an image")), "format"),
        (lambda: client.infer("ward6", inputs(module),
                              outputs=[module.InferRequestedOutput("hue")]), "unknown output"),
    ]
    for call, words in cases:
        with pytest.raises(InferenceServerException) as raised:
            call()
        assert words in raised.value.message(), raised.value.message()


def batch_inputs(module, images, whites, circles):
    """A batch as tritonclient users send one: every per-image input of shape [N]."""
    arrays = [("image", np.array(images, dtype=np.object_), "BYTES"),
              ("white", np.array(whites, dtype=np.float64), "FP64")]
    arrays += [(k, np.array([c[j] for c in circles], dtype=np.float64), "FP64")
               for j, k in enumerate(("cx", "cy", "r"))]
    return built(module, arrays)


# Eight different requests from the committed fixtures: a sphere under whites that move its
# brightness, and another sphere (tests/fixtures/features/manifest.csv).
BATCH_WHITES = [0.8, 0.4, 1.6, 0.2, 3.2, 1.0, 1.0, 0.6]
OTHER = (FIXTURE.parent / "sphere_gray8.png", (52.35, 48.7, 40.3))


@pytest.mark.parametrize("transport", ["http", "grpc"])
def test_a_batch_answers_what_single_requests_answer(server, transport):
    module = httpclient if transport == "http" else grpcclient
    client = server[transport]
    images = [FIXTURE.read_bytes()] * 8
    circles = [(CIRCLE["cx"], CIRCLE["cy"], CIRCLE["r"])] * 8
    images[5], circles[5] = OTHER[0].read_bytes(), OTHER[1]
    result = client.infer("ward6", batch_inputs(module, images, BATCH_WHITES, circles))
    labels = result.as_numpy("label")
    probabilities = result.as_numpy("probabilities")
    assert labels.shape == (8, 1) and probabilities.shape == (8, 6)
    assert result.as_numpy("ward").shape == (8, 3, 3)
    for i, (image, white, circle) in enumerate(zip(images, BATCH_WHITES, circles)):
        single = client.infer("ward6", batch_inputs(module, [image], [white], [circle]))
        assert labels[i].tolist() == single.as_numpy("label").tolist(), i
        assert np.array_equal(probabilities[i], single.as_numpy("probabilities")), i
    assert len({tuple(p) for p in probabilities}) > 1, "the batch's images differ"

    images[3] = b"not an image"
    with pytest.raises(InferenceServerException) as raised:
        client.infer("ward6", batch_inputs(module, images, BATCH_WHITES, circles))
    message = raised.value.message()
    assert "image 3 of the batch of 8" in message, message
    if transport == "http":
        assert raised.value.status() == "400"
    else:
        assert "INVALID_ARGUMENT" in str(raised.value.status()), raised.value.status()


def activate(server, version):
    request = urllib.request.Request(
        f"{server['admin']}/admin/v1/models/demo/versions/{version}/activate", method="POST",
        headers={"Authorization": f"Bearer {TOKEN}"})
    with urllib.request.urlopen(request) as response:
        return json.loads(response.read())


def test_a_model_swap_during_traffic_loses_no_request(server):
    seen, failures = [], []
    stop = threading.Event()

    def traffic(module, url):
        # tritonclient's HTTP client runs on gevent: one client per thread.
        client = module.InferenceServerClient(url)
        while not stop.is_set():
            try:
                result = client.infer("demo", inputs(module))
                version = result.get_response()["model_version"] if module is httpclient \
                    else result.get_response().model_version
                seen.append((module.__name__, version))
            except Exception as e:  # noqa: BLE001 - every failure is a finding
                failures.append(repr(e))

    threads = [threading.Thread(target=traffic, args=(httpclient, server["http_url"])),
               threading.Thread(target=traffic, args=(grpcclient, server["grpc_url"]))]
    for t in threads:
        t.start()
    time.sleep(0.5)
    activate(server, 2)
    time.sleep(0.5)
    stop.set()
    for t in threads:
        t.join()
    activate(server, 1)
    assert not failures, failures[:3]
    versions = [v for _, v in seen]
    assert set(versions) == {"1", "2"}, versions
    # Once version 2 answers, version 1 does not come back (per transport).
    for name in {m for m, _ in seen}:
        mine = [v for m, v in seen if m == name]
        assert mine == sorted(mine), mine
