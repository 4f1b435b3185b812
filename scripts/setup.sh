#!/usr/bin/env bash
# Sourced by the README's commands: makes sure libtorch (torch==2.13.0 from PyPI) is in the
# cache outside the clone and exports what tch's build needs. Idempotent and fast once cached.
set -euo pipefail
GAITSWEEP_CACHE="${GAITSWEEP_CACHE:-$HOME/.cache/gaitsweep}"
TORCH_VERSION="2.13.0"
VENV="$GAITSWEEP_CACHE/venv"
mkdir -p "$GAITSWEEP_CACHE"
if ! "$VENV/bin/python" -c "import torch, sys; sys.exit(0 if torch.__version__.split('+')[0] == '$TORCH_VERSION' else 1)" 2>/dev/null; then
  echo "gaitsweep: installing torch==$TORCH_VERSION into $VENV (once; about 5 GB)" >&2
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install --quiet "torch==$TORCH_VERSION"
fi
# TensorBoard reads the event files `worker train` writes (and the tests read them back).
if ! "$VENV/bin/python" -c "import tensorboard" 2>/dev/null; then
  echo "gaitsweep: installing tensorboard==2.20.0 into $VENV (once)" >&2
  "$VENV/bin/pip" install --quiet "tensorboard==2.20.0"
fi
# The ONNX export's test runs the exported policy in onnxruntime (and torch) to compare.
if ! "$VENV/bin/python" -c "import onnxruntime" 2>/dev/null; then
  echo "gaitsweep: installing onnxruntime==1.32.0 into $VENV (once)" >&2
  "$VENV/bin/pip" install --quiet "onnxruntime==1.32.0"
fi
# tch's build script asks this python for libtorch's location and ABI.
export VIRTUAL_ENV="$VENV"
export PATH="$VENV/bin:$PATH"
export LIBTORCH_USE_PYTORCH=1
export GAITSWEEP_CACHE
