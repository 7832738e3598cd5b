import math

from umbra.connectors.status_figures import error_figure


def test_errors_read_in_millimetres_and_degrees() -> None:
    assert error_figure("error_x", 0.0012) == "x +1.2 mm"
    assert error_figure("error_z", -0.25) == "z -250.0 mm"
    assert error_figure("error_roll", math.radians(-0.4)) == "roll -0.40 deg"
    assert error_figure("gain", 0.123456) == "gain 0.1235"
