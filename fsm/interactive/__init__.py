"""``python -m fsm.interactive --scene clutter3``: the task cycle of section 5.2 run the way the
paper's user ran it, from a local web page. "Both the object and the delivery point are specified
by the user by clicking a mouse on the overhead image of the cluttered table" (section 5): a
click on a block starts the cycle, a click on the table after Grasp Object says where the block
goes, and the system returns to Select/Model, waiting for the next click.

The page shows the overhead image (``#overhead``), one status line (``#status``), the states as
they are entered with their reasons, a live view of the arm and hand, each cycle's files, and
the command that opens the live 3-D recording in the rerun viewer. Modules: :mod:`.server` (HTTP
and Server-Sent Events), :mod:`.hub` (what the page is told and what it asks), :mod:`.driver`
(the task cycle's thread: every cycle, every render), :mod:`.live_view` (the live camera),
``page.html``; the wait states are :mod:`fsm.handlers.wait_for_block` and
:mod:`fsm.handlers.wait_for_place`."""
