"""The model names, apart from the models so the commands can list them without loading torch."""

FORCE_MODELS = ("tdnn", "gp", "lstm", "cnnlstm", "convlstm", "deform-gru")
MATERIAL_MODELS = ("material-dnn", "material-force", "material-curves", "material-timing")
