"""Latency benchmarks behind `dampnet bench` (not used by the rest of the package).

  harness.py       builds and runs the C++ latency harness (bench/bench_mlp.cpp), the HIL budget
                   and the hard-input check of every timed loop configuration
  python_bench.py  Python-side comparisons: numpy, torch, onnxruntime and the runtime's bindings
"""
