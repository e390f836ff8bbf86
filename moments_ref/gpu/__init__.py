"""GPU emulation: what a shader does to the shadow map before any technique reads it.

* :mod:`.filtering`: MSAA resolve of b(z) and the 9² Gaussian (HPG17 §4.1), whole maps.
* :mod:`.onchip`: the HPG17 §4.1 compute shader, block by block in shared memory.
* :mod:`.banks`: shared-memory bank conflicts of its layout.
* :mod:`.bluenoise`: void-and-cluster blue noise and dithered lookups (HPG17 §4.2).
* :mod:`.sat`: summed-area tables of moments (moment soft shadows).

References
----------
HPG17, Slides : see docs/bib.md.
"""
