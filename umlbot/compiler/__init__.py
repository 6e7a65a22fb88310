"""The model language: load a model folder, check it, compile it, draw it.

The orchestrator needs only `umlbot.compiler.compiled` (the compiled file's types, `load_compiled`) and
`umlbot.compiler.expr` (the expression tree); the loader, checker and renderer live in their own modules
so that reading a compiled model stays light.
"""
