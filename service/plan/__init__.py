"""Capacity planning (``softevo plan``): what a grid of treatments costs and how long it takes
on given cores, coordinators and GPUs (``model``), from a simulated dispatch of its
generations (``dispatch``)."""
