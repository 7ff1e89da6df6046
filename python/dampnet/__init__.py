"""dampnet: neural damper models from shock-dyno data.

Train the thesis's MLP (velocity, acceleration, voltage -> force), diagnose
what physics it misses, export it to a C header, and run it in a real-time
C++ quarter-car loop. Units are SI throughout.
"""

from dampnet.model import MlpModel, ModelError

__all__ = ["MlpModel", "ModelError", "__version__"]

try:
    from importlib.metadata import version as _version

    __version__ = _version("dampnet")
except Exception:  # running from a source tree without installation
    __version__ = "0.0.0+local"
