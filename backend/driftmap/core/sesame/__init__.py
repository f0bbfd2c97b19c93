"""SESAME ([SESAME]): Shannon-entropy saliency masks, Algorithm 1, and the glare classifier.

Modules: ``masks`` (entropy masks, saliency scores, masked SAD, BuildSalientDatabase; sections 3.2-3.4)
and ``glare_svm`` (the linear SVM that removes glare-struck frames; section 3.5).
"""
