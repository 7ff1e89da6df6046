"""`dampnet info`: the installed runtime's version and where its C library and headers are."""

from __future__ import annotations

from dampnet.commands.common import error


def add_parser(subparsers):
    p = subparsers.add_parser("info", help="print versions and the C library/header locations")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:

    from dampnet import __version__, _core, paths

    try:  # an install that lost its C side: one line, not a traceback
        headers, library = paths.include_dirs()[0], paths.shared_library()
    except FileNotFoundError as e:
        return error(str(e))
    print(f"dampnet {__version__} (C++ core {_core.__version__})")
    print(f"headers:        {headers}")
    print(f"shared library: {library}")
    info = getattr(_core, "BUILD_INFO", None)
    if info:
        print(f"MLP kernel:     {info['kernel_isa']} backend (cpp/include/dampnet/kernel/); "
              f"built with {info['compiler']}, flags '{info['flags']}'")
        print("                (CMake options DAMPNET_AVX2=AUTO|ON|OFF, DAMPNET_AVX512=OFF|AUTO|ON set DN_KERNEL_BACKEND)")
    return 0
