"""Sensor models: turn readings with sensor poses into log-odds evidence on the grid."""
