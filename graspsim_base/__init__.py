"""The shared base every layer of graspsim stands on: the command-line contract
(:mod:`graspsim_base.cli`), files written whole (:mod:`graspsim_base.files`) and the process pool
(:mod:`graspsim_base.pool`). It imports only the standard library and numpy."""
