#!/usr/bin/env python3
"""A batch of N against N single requests sent one after another, with tritonclient over
HTTP (or gRPC), alternating rounds on one server: images per second of each, and the ratio.

    target/release/reflectance serve --models models --default-model ward6 &
    python3 scripts/loadtest/batch.py                 # N = 8, 20 rounds, HTTP
    python3 scripts/loadtest/batch.py --grpc localhost:8081 --n 8

The images are the committed fixture sphere (tests/fixtures/features/sphere_rgb8.png) under
N different whites, so each image of a batch is a request of its own.
"""
import argparse
import pathlib
import statistics
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
FIXTURE = ROOT / "tests" / "fixtures" / "features" / "sphere_rgb8.png"
CIRCLE = (96.5, 94.25, 85.0)


def inputs(module, images, whites):
    arrays = [("image", np.array(images, dtype=np.object_), "BYTES"),
              ("white", np.array(whites, dtype=np.float64), "FP64")]
    arrays += [(k, np.full(len(images), v, dtype=np.float64), "FP64")
               for k, v in zip(("cx", "cy", "r"), CIRCLE)]
    built = []
    for name, array, datatype in arrays:
        tensor = module.InferInput(name, list(array.shape), datatype)
        tensor.set_data_from_numpy(array)
        built.append(tensor)
    return built


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--http", default="localhost:8080")
    parser.add_argument("--grpc", help="use gRPC at this address instead")
    parser.add_argument("--model", default="ward6")
    parser.add_argument("--n", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=20)
    args = parser.parse_args()
    if args.grpc:
        import tritonclient.grpc as module
        client = module.InferenceServerClient(args.grpc)
    else:
        import tritonclient.http as module
        client = module.InferenceServerClient(args.http)
    image = FIXTURE.read_bytes()
    whites = [0.4 + 0.1 * i for i in range(args.n)]
    batch = inputs(module, [image] * args.n, whites)
    singles = [inputs(module, [image], [w]) for w in whites]
    client.infer(args.model, batch)  # warm
    times = {"batch": [], "singles": []}
    for _ in range(args.rounds):
        t = time.perf_counter()
        client.infer(args.model, batch)
        times["batch"].append(time.perf_counter() - t)
        t = time.perf_counter()
        for one in singles:
            client.infer(args.model, one)
        times["singles"].append(time.perf_counter() - t)
    rate = {k: args.n / statistics.median(v) for k, v in times.items()}
    print(f"{args.n} images, {args.rounds} alternating rounds, median:")
    for k in ("batch", "singles"):
        print(f"  {k:8s} {statistics.median(times[k]) * 1e3:8.1f} ms  {rate[k]:8.1f} images/s")
    print(f"  batch / singles: {rate['batch'] / rate['singles']:.2f}x")


if __name__ == "__main__":
    main()
