"""What a trained model is exported as, one module per target (`dampnet export`):

  header.py   the generated C/C++ header (model.h): the contract between training and the runtime
  onnx.py     the ONNX graph of the MLP with its input handling and scalings
  fmu/        the FMU (FMI 2.0 / 3.0) of the damper or of the quarter car
  mcu.py      the ready-to-build microcontroller folder (`dampnet export MODEL --target CPU`)

`from dampnet.export import X` gives the header's and the ONNX graph's names (fmu/ and mcu.py
build on the simulation, so they are imported by their own names: dampnet.export.fmu,
dampnet.export.mcu).
"""

from dampnet.export.header import check_prefix, header_text, write_header
from dampnet.export.onnx import ONNX_OPSET, onnx_graph, write_onnx

__all__ = ["ONNX_OPSET", "check_prefix", "header_text", "onnx_graph", "write_header", "write_onnx"]
