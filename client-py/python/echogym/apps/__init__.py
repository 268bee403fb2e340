"""Applications built on the library: ``echogym demo`` (:mod:`echogym.apps.demo`),
``echogym ultrasound`` (:mod:`echogym.apps.ultrasound`) and the plots drawn after
``echogym calibrate`` (:mod:`echogym.apps.calibration_plots`). Training is its own
application, :mod:`echogym.train`.

The figures need matplotlib: ``pip install 'echogym[plots]'``. Nothing in the library
(``import echogym``) imports this package.
"""
