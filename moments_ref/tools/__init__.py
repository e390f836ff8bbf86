"""Tools that measure the library: nothing below imports them.

* :mod:`.bench`: ``moments-ref bench``, throughput as same-run ratios.
* :mod:`.stability`: ``moments-ref stability``, where float32 breaks down.
* :mod:`.figures`: ``moments-ref figure3|figure4``, HPG17 Figures 3 and 4 as data and plots.
* :mod:`.strategies`: hypothesis strategies for depth distributions and moments.
* :mod:`.decoders`: the 32-bit decoder choice of docs/formats.md, measured.
* :mod:`.intervals`: intervals for figures from random rows (a quantile's, a maximum's, a share's).
* :mod:`.random_figures`: the docs' figures from random rows no other command writes (docs/msm6.md).
* :mod:`.claim_parameters`: the unstated parameters of the EVSM and VWSS claims, varied.
* :mod:`.apidoc`: docs/api.md and the layout tables, generated from the package.
* :mod:`.layout`: the layers, read from the folders.
* :mod:`.references`: the numbered References sections, written from docs/bib.md.
* :mod:`.mutation`: mutation scores of the package's own modules (docs/testing.md).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""
