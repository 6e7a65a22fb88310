"""`python -m umlbot.services.serve`: what `umlbot service` becomes once it has read its arguments."""

from umlbot.services.serve import main

main()
