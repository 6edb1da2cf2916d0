"""Geometry: exact segments, arc-length parameterised paths, layers and their sources.

``segments`` (line, arc, polynomial curve), ``path`` (:class:`Path`), ``layer``
(:class:`Layer`: outer boundaries, holes, open paths), ``shapes`` (parametric shapes),
``dxf`` / ``svg`` / ``text`` / ``airfoil`` (importers; ezdxf, svgpathtools), ``chain``
(loose segments into contours), ``hatch`` (scan and jump vectors; shapely) and ``load``
(one entry point for every source). Importers load their libraries only when used.
"""
