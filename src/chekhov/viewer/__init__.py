"""Pictures (``render``: matplotlib PNGs) and the interactive 3D viewer (``app.Viewer``, on
viser: ``pip install 'chekhov[viewer]'``). Import ``chekhov.viewer.app`` explicitly; this
package does not import viser."""
