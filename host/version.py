"""The program's version: the bottom of the import graph, importing nothing.

``host.__version__`` and every file that names the software (the report, the result's
provenance, ``python3 -m host --version``) read it from here, so that no module imports the
package root for it.
"""

__version__ = "0.1.0"
