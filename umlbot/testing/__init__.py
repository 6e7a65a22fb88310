"""Fakes of the C libraries the drivers use, as package code a user can test a model with: one
module per library (`umlbot.testing.pigpio`: a `pigpio.pi` with its daemon-side scripts and an
HC-SR04; `umlbot.testing.lgpio`: the `lgpio` module). A robot never loads them: the connection
modules import one only when the environment asks for it (`UMLBOT_FAKE_PIGPIO`, `UMLBOT_FAKE_LGPIO`)."""
