"""Searchlights, occlusion, rewards and scenarios of stealth-nav.

Also the RL environment node speaking the rl_msgs protocol.
"""
