"""The configuration: node parameters, parameter files, robot model, controllers, security policy, installed files."""
