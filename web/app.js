// gvd web app
