"""Camera calibration: zoom camera models, calibration math and the Sony FCB zoom driver."""
