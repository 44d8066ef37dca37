"""Whether the craft may fly: arming rules, the failsafe, the supervisor's safety task, the built-in test."""
