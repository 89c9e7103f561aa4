"""The model names and the model file format's version, apart from the models so the commands can
list them and read a header without loading torch."""

FORCE_MODELS = ("tdnn", "gp", "lstm", "cnnlstm", "convlstm", "deform-gru")
MATERIAL_MODELS = ("material-dnn", "material-force", "material-curves", "material-timing", "material-rises")

FORMAT_VERSION = 1  # of the model header this version writes and reads; a file of a later one is refused
