"""microfab: from a part drawing and a micro-fabrication machine to accurate machine commands.

The package is organised by concept (see ``docs/architecture.md``): ``plants`` holds the
digital twins, ``control`` the controllers and learners, ``sim`` the closed-loop simulators,
``machines`` the ``Machine`` protocol and its implementations, ``process`` the physics of
what is made, ``experiments`` the reproductions of the seed papers and ``report`` the
figures and HTML report.
"""

__version__ = "0.1.0"
