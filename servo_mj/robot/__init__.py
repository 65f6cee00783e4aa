"""The ServoBot in MuJoCo: names and paths, physics settings, model loading, gaits, the bot.

Imports point down: ``constants`` and ``settings`` → ``model`` → ``gaits`` → ``bot``.
"""
