"""Fly a design: Paper B's multirotor model, mixer and cascade controller.

Modules, one job each: ``vehicle`` (rigid-body parameters from the optimizer's model and
the 6-DOF equations of motion, thesis 2.39-2.43 / B.7-B.11), ``actuators`` (Paper C's
first-order-plus-delay rotor), ``mixer`` (B.27 for any layout, saturation rule),
``controller`` (quaternion attitude -> rate -> mixer cascade, altitude hold, gain rule),
``maneuvers`` (the closed-loop simulation and the named maneuvers), ``metrics`` (rise,
overshoot, settling), ``ranking`` (time constant vs closed-loop rise time), ``design``
(a chosen design set up and flown), ``uncertainty`` (the spread of the measured
constants, drawn), ``reference`` (tight integrations the step and the rotor lag are
checked against) and the batch flight, many designs at once as numpy arrays with the scalar
loop's figures: ``batch_designs`` (the designs), ``batch_loop`` (the tick) and ``batch``
(``fly_batch``). Plain numbers in, plain numbers out: no device code. Above
``optimizer.model`` (a vehicle is built from a design's numbers), below ``optimizer.solve``
(which flies candidates for ``optimize --max-roll-rise-ms``) and ``optimizer.sweep``.
"""
