"""Untrusted team code: everything between a team's uploaded module and the robot it drives.

- :mod:`~robo_comp.sandbox.contract`: what an uploaded module must look like (checked before it runs);
- :mod:`~robo_comp.sandbox.policy`: the RestrictedPython policy the module is compiled and run under;
- :mod:`~robo_comp.sandbox.explain`: the policy's refusals in a student's words;
- :mod:`~robo_comp.sandbox.child`: the child process that runs the module under OS limits;
- :mod:`~robo_comp.sandbox.parent`: the parent's handle on that child (:class:`~robo_comp.sandbox.parent.Sandbox`).

This package imports nothing at import time: the child process imports only what it needs
before it drops its privileges.
"""
