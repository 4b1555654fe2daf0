"""What the command-line verbs share: argument groups and settings (``common``), option checks (``options``),
in memory or streamed (``memory_path``), output paths (``paths``), the robot as built (``asbuilt``) and the model
file written beside a result (``model_files``). The verbs themselves are the modules of :mod:`oed.cli`; none
imports another.
"""
