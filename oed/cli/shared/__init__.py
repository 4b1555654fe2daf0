"""What the command-line verbs share: argument groups and how options reach a verb's library function
(``common``), option types (``options``), output paths (``paths``), the options of the robot as built
(``asbuilt``) and the verb table (``verbs``). The verbs themselves are the modules of :mod:`oed.cli`; none imports
another, and each calls one library function of :mod:`oed.workflows`.
"""
