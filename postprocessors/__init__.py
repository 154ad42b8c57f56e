"""camtool's built-in post-processors, one package per controller format: ``rapid`` (ABB
RAPID), ``inform`` (Yaskawa INFORM) and ``csv`` (joint table). Each holds ``dialect``,
``writer``, ``parser`` and ``checker`` modules and one plugin class; they are registered
in ``camtool.program.registry``."""
