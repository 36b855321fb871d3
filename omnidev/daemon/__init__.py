"""omnidevd, the pointer daemon: config, pipeline, systemd notification, control socket."""
