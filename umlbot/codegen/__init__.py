"""Code generation: a compiled model's swimlanes as a C++17 CMake project (`umlbot generate cpp`).

`generate_cpp(model, out_dir)` writes readable, deterministic sources (the same model gives the
same bytes) with the runtime shipped in this package (`umlbot/codegen/runtime/`) copied beside
them; `build_cpp` configures and builds the project with CMake and Ninja when the toolchain is
installed (`missing_toolchain` says what is not). docs/codegen.md tells users the rest.
"""

from umlbot.codegen.build import APT_LINE, BuildError, build_cpp, cached_program, missing_toolchain
from umlbot.codegen.cpp import GenerateError, generate_cpp, program_name, project_files, render_cpp

__all__ = [
    "APT_LINE",
    "BuildError",
    "GenerateError",
    "build_cpp",
    "cached_program",
    "generate_cpp",
    "missing_toolchain",
    "program_name",
    "project_files",
    "render_cpp",
]
