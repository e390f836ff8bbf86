"""GPU emulation: what a shader does to the shadow map before any technique reads it.

* :mod:`.filtering`: MSAA resolve of b(z) and the 9² Gaussian (HPG17 §4.1), whole maps.
* :mod:`.onchip`: the HPG17 §4.1 compute shader, block by block in shared memory.
* :mod:`.banks`: shared-memory bank conflicts of its layout.
* :mod:`.bluenoise`: void-and-cluster blue noise and dithered lookups (HPG17 §4.2).
* :mod:`.sat`: summed-area tables of moments (moment soft shadows).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""
