"""Tools that measure the library: nothing below imports them.

* :mod:`.bench`: ``moments-ref bench``, throughput as same-run ratios.
* :mod:`.stability`: ``moments-ref stability``, where float32 breaks down.
* :mod:`.figures`: ``moments-ref figure3|figure4``, HPG17 Figures 3 and 4 as data and plots.
* :mod:`.strategies`: hypothesis strategies for depth distributions and moments.
* :mod:`.decoders`: the 32-bit decoder choice of docs/formats.md, measured.
* :mod:`.claim_parameters`: the unstated parameters of the EVSM and VWSS claims, varied.
* :mod:`.apidoc`: docs/api.md and the layout tables, generated from the package.
* :mod:`.layout`: the layers, read from the folders.
* :mod:`.mutation`: mutation scores of the package's own modules (docs/testing.md).

References
----------
HPG17, VWSS : see docs/bib.md.
"""
