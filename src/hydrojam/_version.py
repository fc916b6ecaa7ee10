"""hydrojam's version, on the ground floor so that any layer may record it without importing the
package's top (which loads the materials and the design schema)."""

__version__ = "0.1.0"
