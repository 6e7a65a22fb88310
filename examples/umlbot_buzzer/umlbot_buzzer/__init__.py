"""An example umlbot plugin: a passive buzzer, played with a square wave at the tone's frequency."""
