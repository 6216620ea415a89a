"""Pure geometry, no MuJoCo: rotations (``so3``), rigid transforms (``se3``), polylines and
closest points (``path``), numpy's elementwise rules on floats (``floats``). Every other
package may import it; it imports only numpy/scipy."""
