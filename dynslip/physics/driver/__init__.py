"""The run driver: a protocol's stages segment by segment (:mod:`.simulate`), one member's
compiled stages (:mod:`.member`), lockstep batches (:mod:`.batch`), the mesh check before a
run (:mod:`.meshcheck`) and the failures a run reports (:mod:`.failures`)."""
